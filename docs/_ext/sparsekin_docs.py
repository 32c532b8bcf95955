"""Sphinx extension of the sparsekin site: what the pages show is made from the code at build time.

* **Gallery.** A page per model file of ``examples/``: its opening comment as the text,
  the drawing at t = 0 (`sparsekin.plots.draw_mechanism`), a frame of its animation
  with the ``[analysis].points`` traced (`sparsekin.plots.save_frame`) and the file
  itself; and an index with every frame, written to ``docs/gallery/``.  A new example is
  a new file in ``examples/`` (and its test in ``tests/test_gallery.py``);
  ``GALLERY_ORDER`` only sets the order.  The forward-dynamics examples of
  ``DYNAMICS_GALLERY`` (in ``examples/dynamics/``, tested in
  ``tests/test_dynamic_gallery.py`` and ``tests/test_dynamics.py``) follow, each with its
  animation.
* **Command line reference**, ``docs/reference/cli.md``, from `sparsekin.cli.build_parser`.
* **Command output.** A line ``<!-- sparsekin: check examples/task5.toml -->`` in a page
  is replaced by the command and what it printed, run in a scratch folder that holds
  ``examples/`` and the models of ``DOC_MODELS``; the files it writes are copied to
  ``docs/generated/`` (``generated/sparsekin-out/task5/point_K.png``).  The exit status
  must be 0, or the one written as ``<!-- sparsekin (exit 3): ... -->``: otherwise the
  build fails.
* **Element reference.** ``docs/elements.md`` must be what ``make_element_reference.py``
  writes, or the build fails.

Everything written is listed in ``GENERATED`` (and in ``.gitignore``); a build rewrites it.
"""

from __future__ import annotations

import contextlib
import io
import math
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

from sphinx.errors import ExtensionError

DOCS = Path(__file__).resolve().parents[1]
ROOT = DOCS.parent
EXAMPLES = ROOT / "examples"
#: What a build writes into docs/ (and .gitignore lists).
GENERATED = (DOCS / "gallery", DOCS / "generated", DOCS / "reference" / "cli.md")
#: Gallery pages first in this order, then any other example by name.
GALLERY_ORDER = (
    "task5", "slider_crank", "four_bar", "watt_six_bar", "quick_return", "excavator", "four_bar_chain", "planetary_gear",
)  # fmt: skip
#: Titles of the gallery pages: every example has one (the build stops on an example without).
GALLERY_TITLES = {
    "task5": "Task 5 linkage",
    "slider_crank": "Slider-crank",
    "four_bar": "Four-bar (crank-rocker)",
    "watt_six_bar": "Watt six-bar",
    "quick_return": "Quick-return (crank and slotted lever)",
    "excavator": "Excavator front",
    "excavator_cylinders": "Excavator front with cylinder composites",
    "planetary_gear": "Planetary gear train",
    "task5_distance": "Task 5 with distance drivers",
    "four_bar_chain": "Four-bar chain (1000 loops)",
    "task5_chain": "Task 5 chain (1000 units)",
    "task5_dynamics": "Task 5 with masses and a payload",
    "lattice": "Lattice of parallelograms (a grid repeat)",
    "rotating_squares": "Rotating squares (an auxetic metamaterial)",
    "rotating_rectangles": "Rotating rectangles",
    "jansen_leg": "Theo Jansen's leg from its link lengths",
    "strandbeest": "A Strandbeest: twelve legs from one drawn leg",
    "n_four_bar": "N-four-bar (IFToMM A02, N = 40) falling through its singular positions",
    "andrews": "Andrews' squeezing mechanism (IFToMM A03)",
    "struck_lattice": "A struck metamaterial: rotating squares with sprung hinges",
}
#: The forward-dynamics examples of the gallery (``examples/dynamics/NAME.toml``), in order:
#: name -> (time shown, s, or None for the file's ``t_end``; clip length, s; frames per
#: second).  Each page has the whole clip; the N-four-bar shows its first 3 s (three of its
#: twenty flat crossings) to keep the build short.
DYNAMICS_GALLERY = {
    "n_four_bar": (3.0, 3.0, 10),
    "andrews": (None, 3.0, 10),
    "struck_lattice": (None, 6.0, 5),
}
#: Examples drawn without labels besides the metamaterials (a chain's or a lattice's names
#: would hide it).
UNLABELLED = ("n_four_bar", "struck_lattice")
#: Lattice metamaterials: drawn whole and animated without labels, with the figure of
#: their size against their opening (`sparsekin.plots.metamaterials.plot_lattice_size`):
#: name -> (two bodies across, two bodies up, the body whose angle is the opening).
METAMATERIALS = {
    "rotating_squares": (("s0_0.a", "s3_0.b"), ("s0_0.a", "s0_3.c"), "s0_0.a"),
    "rotating_rectangles": (("r0_0.rect", "r5_0.rect"), ("r0_0.rect", "r0_3.rect"), "r0_0.rect"),
}
#: The animations of the metamaterials: clip length (s) and frames per second.
METAMATERIAL_CLIP = (6.0, 10)
#: Model files put into the scratch folder of the command examples: a file of the
#: repository, or a Python expression of sparsekin saved as a model file (the pages say
#: how to make them).
DOC_MODELS = {
    "task5_stroke_006.toml": "sparsekin.testset.task5(amplitude=0.06)",
    "triple_parallelogram.toml": ROOT / "tests" / "data" / "triple_parallelogram.toml",
}
#: Where an animation frame of a gallery example is taken, as a fraction of its run.
FRAME_AT = 0.4
#: A larger example (a chain of repeated units) is drawn by its first this many bodies.
GALLERY_MAX_BODIES = 20

DIRECTIVE = re.compile(r"^<!-- sparsekin(?: \(exit (\d+)\))?: (.+?) -->$", re.MULTILINE)


def setup(app):
    app.connect("builder-inited", generate)
    app.connect("source-read", show_command_output)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}


def generate(app) -> None:
    """Write the gallery, the command line reference and the command outputs into docs/."""
    _check_element_reference()
    for path in GENERATED:
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()
    make_gallery(DOCS / "gallery")
    (DOCS / "reference" / "cli.md").write_text(cli_reference(), encoding="utf-8")
    app.sparsekin_outputs = run_commands(sorted(DOCS.rglob("*.md")), DOCS / "generated")


def show_command_output(app, docname, source) -> None:
    """Replace each command line in a page by the command and what it printed."""
    outputs = app.sparsekin_outputs

    def replace(match):
        status, output = outputs[match.group(2)]
        shown = f"$ sparsekin {match.group(2)}\n{output.rstrip()}"
        if status:
            shown += f"\n$ echo $?\n{status}"
        return f"```console\n{shown}\n```"

    source[0] = DIRECTIVE.sub(replace, source[0])


# ---------------------------------------------------------------------- gallery
def gallery_names() -> list[str]:
    names = sorted(path.stem for path in EXAMPLES.glob("*.toml"))
    return [name for name in GALLERY_ORDER if name in names] + [
        name for name in names if name not in GALLERY_ORDER
    ] + list(DYNAMICS_GALLERY)


def example_file(name: str) -> str:
    """The example's model file, relative to the repository."""
    return f"examples/dynamics/{name}.toml" if name in DYNAMICS_GALLERY else f"examples/{name}.toml"


def solve_example(name: str, mechanism):
    """The example's analysis as its page shows it: ``(result, t_end, steps, words)``."""
    import numpy as np

    import sparsekin as sk

    analysis = mechanism.analysis
    with warnings.catch_warnings():
        # over-constrained by design (lattices): their states of self-stress are left out
        warnings.simplefilter("ignore", sk.RedundantConstraintWarning)
        if name not in DYNAMICS_GALLERY:
            times = np.linspace(0.0, analysis.t_end, analysis.steps)
            return sk.solve_kinematics(mechanism, times), analysis.t_end, analysis.steps, ""
        shown = DYNAMICS_GALLERY[name][0] or analysis.t_end
        steps = round((analysis.steps - 1) * shown / analysis.t_end) + 1
        result = sk.solve_dynamics(mechanism, np.linspace(0.0, shown, steps))
    part = f" (the first {shown:g} s of the file's {analysis.t_end:g} s)" if shown < analysis.t_end else ""
    words = (f"{part}, by forward dynamics in {result.n_steps} steps of at most {analysis.max_step:g} s; largest "
             f"energy error {np.max(np.abs(result.energy.balance)):.2g} J")  # fmt: skip
    return result, shown, steps, words


def _count(number: int, word: str, plural: str | None = None) -> str:
    return f"{number} {word if number == 1 else plural or word + 's'}"


def opening_comment(text: str) -> str:
    """The comment lines at the top of a model file, as one paragraph."""
    lines = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        lines.append(line[1:].strip())
    return "\n".join(lines)


def make_gallery(folder: Path) -> None:
    """A page per example and an index, with the pictures, into `folder`."""

    import sparsekin as sk
    from sparsekin.engine.pattern import build_point_map
    from sparsekin.plots import draw_mechanism, save_frame

    (folder / "images").mkdir(parents=True)
    index = [
        "# Gallery",
        "",
        (
            "Each mechanism is a model file of `examples/` that the tests run and check against an "
            "independent reference (`tests/test_gallery.py`). The pictures are drawn when this site is built."
        ),
        "",
        "```{toctree}",
        ":hidden:",
        "",
        *gallery_names(),
        "```",
        "",
    ]
    for name in gallery_names():
        path = ROOT / example_file(name)
        text = path.read_text(encoding="utf-8")
        mechanism = sk.load_model(path)
        analysis = mechanism.analysis
        result, t_end, steps, dynamics = solve_example(name, mechanism)
        trace = analysis.points or ()
        shown, part = None, ""
        if mechanism.n_bodies > GALLERY_MAX_BODIES and name not in METAMATERIALS:
            shown = [mechanism.body_names[k] for k in range(GALLERY_MAX_BODIES)]
            point_map = build_point_map(mechanism)
            trace = [point for point in trace if 0 <= point_map.locate(point)[0] < GALLERY_MAX_BODIES]
            part = f" The pictures show its first {GALLERY_MAX_BODIES} bodies."
        labels = name not in METAMATERIALS and name not in UNLABELLED
        if labels:
            drawing = draw_mechanism(mechanism, result, folder / "images", bodies=shown)
            drawing.rename(folder / "images" / f"{name}.png")
        else:
            save_frame(result, folder / "images" / f"{name}.png", 0.0, labels=False, bodies=shown)
        frame_time = round(FRAME_AT * t_end, 3 - min(0, math.floor(math.log10(t_end))))
        save_frame(result, folder / "images" / f"{name}-frame.png", frame_time, trace=trace, bodies=shown,
                   labels=labels)  # fmt: skip
        if name not in GALLERY_TITLES:
            raise ValueError(f"examples/{name}.toml has no gallery title: add it to GALLERY_TITLES in {__file__}")
        title = GALLERY_TITLES[name]
        traced = f", the paths of {', '.join(trace)} traced" if trace else ""
        page = [
            f"# {title}",
            "",
            opening_comment(text),
            "",
            (
                f"{_count(mechanism.n_bodies, 'body', 'bodies')}, {_count(mechanism.n_joints, 'joint')}, "
                f"{_count(mechanism.n_drivers, 'driver')}; "
                f"analysed over {t_end:g} s in {steps} samples{dynamics}.{part}"
            ),
            "",
            f"![{title} at t = 0](images/{name}.png)",
            "",
            f"A frame of its animation at t = {frame_time:g} s{traced}:",
            "",
            f"![{title} at t = {frame_time:g} s](images/{name}-frame.png)",
            "",
            *metamaterial_section(name, result, folder / "images"),
            *dynamics_section(name, result, trace, labels, shown, folder / "images"),
            "```bash",
            f"sparsekin check {example_file(name)}",
            f"sparsekin run {example_file(name)} --plot",
            f"sparsekin animate {example_file(name)} --out {name}.gif",
            "```",
            "",
            f"## The model file: `{example_file(name)}`",
            "",
            "```toml",
            text.rstrip(),
            "```",
            "",
        ]
        (folder / f"{name}.md").write_text("\n".join(page), encoding="utf-8")
        first_sentence = opening_comment(text).replace("\n", " ").split(". ")[0].rstrip(".")
        index += [f"## [{title}]({name}.md)", "", f"{first_sentence}.", "",
                  f"[![{title}](images/{name}-frame.png)]({name}.md)", ""]  # fmt: skip
    (folder / "index.md").write_text("\n".join(index), encoding="utf-8")


def dynamics_section(name: str, result, trace, labels: bool, bodies, images: Path) -> list[str]:
    """For a forward-dynamics example: its animation (of `bodies`, or all when None)."""
    if name not in DYNAMICS_GALLERY:
        return []
    from sparsekin.plots import animate

    _, duration, fps = DYNAMICS_GALLERY[name]
    clip = animate(result, images / f"{name}.gif", trace=trace, fps=fps, duration=duration, labels=labels,
                   bodies=bodies)  # fmt: skip
    pace = "real time" if math.isclose(duration, result.times[-1]) else f"{duration / result.times[-1]:.3g} × slower"
    return [f"The run, animated ({clip.n_frames} frames, {pace}):", "", f"![{name} animated](images/{name}.gif)", ""]


def metamaterial_section(name: str, result, images: Path) -> list[str]:
    """For a lattice metamaterial: its animation, and its size against its opening."""
    if name not in METAMATERIALS:
        return []
    from sparsekin.plots import animate
    from sparsekin.plots.metamaterials import plot_lattice_size

    across, up, body = METAMATERIALS[name]
    duration, fps = METAMATERIAL_CLIP
    animate(result, images / f"{name}.gif", fps=fps, duration=duration, labels=False)
    plot_lattice_size(result, across, up, body, images / f"{name}-size.png")
    return [
        "The whole run, animated:", "", f"![{name} animated](images/{name}.gif)", "",
        (f"What a metamaterial researcher reads off it: the lattice's width (centre of {across[0]} to centre "
         f"of {across[1]}) and height ({up[0]} to {up[1]}) against the opening angle (of {body}), and "
         "Poisson's ratio −dε_y/dε_x from the samples:"),
        "", f"![{name}: size against opening](images/{name}-size.png)", "",
    ]  # fmt: skip


# ---------------------------------------------------------------------- command line
def cli_reference() -> str:
    """The command line reference, from the argument parser."""
    import argparse

    from sparsekin.cli import build_parser

    parser = build_parser()
    lines = [
        "# Command line",
        "",
        (
            "Generated from `sparsekin.cli.build_parser()` when the site is built. Exit status of every "
            "command: 0 on success, 2 on a bad model file or bad arguments (one line on stderr), "
            "3 when the analysis stops (`run` and `animate` still write what was solved); "
            "`check` exits with 1 for a model with a problem."
        ),
        "",
        "```text",
        parser.format_usage().strip(),
        "```",
        "",
    ]
    subparsers = next(action for action in parser._actions if isinstance(action, argparse._SubParsersAction))
    for name, subparser in subparsers.choices.items():
        lines += [f"## `sparsekin {name}`", "", subparser.description or "", "", "```text",
                  subparser.format_usage().strip(), "```", "", "| argument | meaning |", "|---|---|"]  # fmt: skip
        for action in subparser._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            if action.option_strings:
                shown = ", ".join(action.option_strings) + (f" {action.metavar}" if action.metavar else "")
            else:
                shown = action.metavar or action.dest
            lines.append(f"| `{shown}` | {(action.help or '').replace('|', '&#124;')} |")
        lines.append("")
    return "\n".join(lines)


def run_commands(pages, destination: Path) -> dict[str, tuple[int, str]]:
    """Run every command named in `pages`, once each, in a scratch folder; copy what they
    wrote to `destination`.  Returns the exit status and the output of each command."""
    import sparsekin
    import sparsekin.testset  # named in DOC_MODELS
    from sparsekin.cli import main

    outputs: dict[str, tuple[int, str]] = {}
    with tempfile.TemporaryDirectory(prefix="sparsekin-docs-") as scratch_name:
        scratch = Path(scratch_name)
        for name, source in DOC_MODELS.items():
            if isinstance(source, Path):
                shutil.copy(source, scratch / name)
            else:
                sparsekin.save_model(eval(source, {"sparsekin": sparsekin}), scratch / name)
        (scratch / "examples").symlink_to(EXAMPLES, target_is_directory=True)
        inputs = set(scratch.iterdir())
        for page in pages:
            for match in DIRECTIVE.finditer(page.read_text(encoding="utf-8")):
                expected, command = int(match.group(1) or 0), match.group(2)
                if command in outputs:
                    continue
                printed = io.StringIO()
                with (
                    contextlib.chdir(scratch),
                    contextlib.redirect_stdout(printed),
                    contextlib.redirect_stderr(printed),
                ):
                    status = main(shlex.split(command))
                if status != expected:
                    raise ExtensionError(f"{page.relative_to(DOCS)}: `sparsekin {command}` exited with {status}, "
                                         f"expected {expected}:\n{printed.getvalue()}")  # fmt: skip
                outputs[command] = (status, printed.getvalue())
        for path in scratch.iterdir():
            if path not in inputs:
                target = destination / path.name
                target.parent.mkdir(parents=True, exist_ok=True)
                (shutil.copytree if path.is_dir() else shutil.copy)(path, target)
    return outputs


def _check_element_reference() -> None:
    check = subprocess.run([sys.executable, str(DOCS / "make_element_reference.py"), "--check"],
                           capture_output=True, text=True, check=False)  # fmt: skip
    if check.returncode:
        raise ExtensionError(check.stderr.strip())
