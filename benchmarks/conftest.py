import sys
from pathlib import Path

# The benchmarks build their models with the example scripts and the tests' helpers.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
