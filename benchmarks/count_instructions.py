"""Instructions per time step, counted by valgrind's callgrind: a measure the shared machine's noise cannot move.

    valgrind --tool=callgrind --callgrind-out-file=/dev/null python3 benchmarks/count_instructions.py CHECKOUT MODEL N

runs `solve_kinematics(linear_solver="refactor")` on MODEL (``small``: task5_chain(3), 90
coordinates; ``chain``: task5_chain(300), 9 000 coordinates) over N steps of 0.01 s with the
sparsekin of the folder CHECKOUT.  Two runs with different N, their difference divided by
the difference of N, give the instructions of one step without the fixed costs (imports,
pattern, first sample).  Run each once beforehand so that numba's cache is warm under
valgrind too (valgrind reports another CPU, so the native cache does not serve).  Used to
compare two commits where wall-clock timings drift by 2× between runs
(docs/design-notes.md, "Checking a refactoring for slowdowns").
"""

import sys

import numpy as np

if __name__ == "__main__":
    sys.path.insert(0, sys.argv[1])

import sparsekin as sk  # noqa: E402
from sparsekin import testset  # noqa: E402

MODELS = {"small": lambda: testset.task5_chain(3), "chain": lambda: testset.task5_chain(300)}

if __name__ == "__main__":
    mechanism = MODELS[sys.argv[2]]()
    n_steps = int(sys.argv[3])
    sk.solve_kinematics(mechanism, np.arange(n_steps + 1) * 0.01, linear_solver="refactor")
