"""``KinematicsResult.to_dataframe``: the same numbers as ``point`` and ``joint``, in a
table indexed by time with (kind, name, quantity) columns."""

import sys

import numpy as np
import pytest

from sparsekin import solve_kinematics
from sparsekin.testset import task5

pd = pytest.importorskip("pandas", reason='to_dataframe needs pandas: pip install "sparsekin[pandas]"')


@pytest.fixture(scope="module")
def result():
    return solve_kinematics(task5(), np.linspace(0.0, 2.0, 21))


def test_every_point_and_joint_column_is_the_result_s_own(result):
    table = result.to_dataframe()
    assert table.index.name == "t" and np.array_equal(table.index.to_numpy(), result.times)
    assert table.columns.names == ["kind", "name", "quantity"]
    for name in result.point_names:
        position, velocity, acceleration = result.point(name)
        expected = np.column_stack([position, velocity, acceleration])
        assert table["point", name].columns.tolist() == ["x", "y", "vx", "vy", "ax", "ay"]
        assert np.array_equal(table["point", name].to_numpy(), expected)
    labels = result.joint_names
    assert table["joint"].columns.get_level_values("name").unique().tolist() == list(labels)
    for label in labels:
        assert np.array_equal(table["joint", label].to_numpy(), np.column_stack(result.joint(label)))
    assert table["joint", "actuator1"].columns.tolist() == ["stroke", "speed", "accel"]
    assert table["joint", "joints[0]"].columns.tolist() == ["angle", "rate", "accel"]
    assert table.shape == (result.n_times, 6 * len(result.point_names) + 3 * len(labels))


def test_selection_and_the_tidy_form(result):
    table = result.to_dataframe(points=["K", "A"], joints=["actuator2", 0])
    assert table.columns.get_level_values("name").unique().tolist() == ["K", "A", "actuator2", "joints[0]"]
    tidy = table["point"].stack("name", future_stack=True)
    assert tidy.shape == (2 * result.n_times, 6)
    assert np.array_equal(tidy.xs("A", level="name")[["x", "y"]].to_numpy(), result.point("A").position)
    assert result.to_dataframe(points=[], joints=[]).shape == (result.n_times, 0)


def test_a_selection_by_three_levels_neither_warns_nor_copies_the_index_order(result):
    import warnings

    table = result.to_dataframe()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # pandas' PerformanceWarning on an unsorted MultiIndex
        column = table["point", "K", "vy"]
    assert np.array_equal(column.to_numpy(), result.point("K").velocity[:, 1])


def test_unknown_names_say_what_is_known(result):
    with pytest.raises(KeyError, match='unknown point "Q"'):
        result.to_dataframe(points=["Q"])
    with pytest.raises(KeyError, match='unknown joint "nope"'):
        result.to_dataframe(joints=["nope"])


def test_without_pandas_the_error_names_the_extra(result, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match=r'pip install "sparsekin\[pandas\]"'):
        result.to_dataframe()


def test_a_run_without_coordinates_gives_what_it_recorded():
    times = np.linspace(0.0, 1.0, 11)
    kept = solve_kinematics(task5(), times)
    recorded = solve_kinematics(task5(), times, coordinates=False, points=["K"], joints=[12])
    table = recorded.to_dataframe()
    assert table.columns.get_level_values("name").unique().tolist() == ["K", "actuator1"]
    np.testing.assert_allclose(table["point", "K"].to_numpy(), np.column_stack(kept.point("K")), rtol=0, atol=1e-12)
    np.testing.assert_allclose(table["joint", "actuator1"].to_numpy(), np.column_stack(kept.joint("actuator1")),
                               rtol=0, atol=1e-12)  # fmt: skip
