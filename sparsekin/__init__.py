"""sparsekin: kinematic analysis of planar linkages in absolute coordinates."""
from .errors import ConvergenceError, ModelError, SingularJacobianError, SparsekinError
from .laws import Harmonic, Law, Linear, Polynomial, Spline
from .model import (
    GROUND, AbsoluteDriver, Analysis, Body, Mechanism, Revolute, Rigid, RotationalDriver,
    Translational, TranslationalDriver,
)
from .solvers import KinematicsResult, PointMotion, solve_kinematics
