"""What the forward-dynamics gallery pages add to the site build.

Runs ``make_gallery`` of docs/_ext/sparsekin_docs.py on the dynamics entries
(``DYNAMICS_GALLERY``) and on the whole kinematic gallery, in the same process, two rounds
each (the first warms the numba and matplotlib caches), and prints the wall times, their
ratio and the sizes of the dynamics GIFs.  Needs the docs extra (sphinx) and the animate
extra.  Run from the repository: ``python3 benchmarks/measure_dynamics_gallery.py``.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))

import sparsekin_docs as docs  # noqa: E402


def main() -> None:
    everything = docs.gallery_names()
    dynamics = list(docs.DYNAMICS_GALLERY)
    kinematic = [name for name in everything if name not in dynamics]
    times: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory(prefix="sparsekin-gallery-") as scratch:
        for _ in range(2):
            for label, names in (("kinematic", kinematic), ("dynamics", dynamics)):
                docs.gallery_names = lambda names=names: names
                folder = Path(scratch) / label
                shutil.rmtree(folder, ignore_errors=True)
                start = time.perf_counter()
                docs.make_gallery(folder)
                times.setdefault(label, []).append(time.perf_counter() - start)
        print({label: [round(value, 1) for value in values] for label, values in times.items()})
        print(f"dynamics / kinematic, second round: {times['dynamics'][1] / times['kinematic'][1]:.2f}")
        for path in sorted((Path(scratch) / "dynamics" / "images").glob("*.gif")):
            print(f"{path.name}: {path.stat().st_size / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
