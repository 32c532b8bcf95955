"""Write docs/elements.md, the reference of every joint, driver, load and law kind, from their declarations.

    python3 docs/make_element_reference.py          # rewrites docs/elements.md
    python3 docs/make_element_reference.py --check  # exit 1 if docs/elements.md is stale

The page is generated, never edited by hand: each kind's class docstring, file keys,
equations and own coordinate come from `sparsekin.model.elements`, `sparsekin.model.composites` and
`sparsekin.model.laws`.
tests/test_docs.py runs the check.
"""

from __future__ import annotations

import inspect
import sys
from pathlib import Path

from sparsekin.model.composites import COMPOSITE_KINDS
from sparsekin.model.elements import DRIVER_KINDS, JOINT_KINDS, LOAD_KINDS
from sparsekin.model.laws import BUILT_IN_LAWS

PAGE = Path(__file__).resolve().parent / "elements.md"


def _keys(kind) -> str:
    keys = kind.file_keys
    parts = []
    if keys.required:
        parts.append("required " + ", ".join(f"`{key}`" for key in keys.required))
    if keys.forms:
        parts.append("either " + " or ".join(" + ".join(f"`{key}`" for key in form) for form in keys.forms))
    if keys.optional:
        parts.append("optional " + ", ".join(f"`{key}`" for key in keys.optional))
    return "; ".join(parts)


def _description(kind) -> str:
    return " ".join(line.strip() for line in inspect.getdoc(kind).splitlines())


def _paragraphs(kind) -> list[str]:
    """The class docstring as Markdown paragraphs, its ``*`` lists kept as lists."""
    lines: list[str] = []
    for paragraph in inspect.getdoc(kind).split("\n\n"):
        items: list[str] = []
        for line in paragraph.splitlines():
            if line.startswith("* ") or not items:
                items.append(line.strip())
            else:
                items[-1] += " " + line.strip()
        lines += [*items, ""]
    return lines


def _element(kind, section: str) -> list[str]:
    lines = [f'### `type = "{kind.type_name}"` (`sparsekin.{kind.__name__}`)', "", _description(kind), ""]
    lines.append(f"- keys: {_keys(kind)}")
    equations = ", ".join(kind.equation_names)
    lines.append(f"- equations ({kind.n_equations}): {equations}")
    if section == "drivers":
        lines.append(f"- laws: {', '.join(f'`{name}`' for name in kind.law_fields)} (one per equation)")
    if kind.output_names:
        columns = ", ".join(f"`J.{suffix}`" for suffix in kind.output_names)
        where = f"in `joints.csv` as {columns}" if section == "joints" else "in Python only"
        lines.append(f"- own coordinate: yes, {where} (`result.{section[:-1]}(name)`)")
    else:
        lines.append("- own coordinate: none")
    if "limits" in kind.file_keys.keys:
        lines.append("- `limits = [min, max]` on its own coordinate: checked by `check`, warned during a run")
    if section == "joints":
        columns = ("fx", "fy", "torque") if kind.reaction_torque else ("fx", "fy")
        lines.append(f"- forces: {', '.join(f'`J.{name}`' for name in columns)} in `forces.csv` (`result.reaction(name)`)")
    else:
        columns = (*kind.force_names, "power")
        lines.append(f"- forces: {', '.join(f'`D.{name}`' for name in columns)} in `forces.csv` "
                     "(`result.driver_force(name)`)")  # fmt: skip
    return [*lines, ""]


def reference() -> str:
    lines = [
        "# Element reference",
        "",
        "Generated from the element declarations by `docs/make_element_reference.py`; do not edit.",
        "The model-file contract is [model-format.md](model-format.md); adding a kind is",
        "[adding-an-element.md](adding-an-element.md).",
        "",
        "## Joints (`[[joints]]`)",
        "",
    ]
    for kind in JOINT_KINDS.values():
        lines += _element(kind, "joints")
    lines += ["## Drivers (`[[drivers]]`)", ""]
    for kind in DRIVER_KINDS.values():
        lines += _element(kind, "drivers")
    lines += ["## Loads (`[[loads]]`)", ""]
    for kind in LOAD_KINDS.values():
        lines += [f'### `type = "{kind.type_name}"` (`sparsekin.{kind.__name__}`)', "", _description(kind), "",
                  f"- keys: {_keys(kind)}"]  # fmt: skip
        if kind.n_laws:
            lines.append(f"- `value`: {kind.n_laws} component{'s' * (kind.n_laws > 1)}, each a number or a law table")
        lines.append("")
    lines += ["## Composites (`[[composites]]`)", "",
              "A composite stands for several blocks written by hand; the reader expands it into them.", ""]  # fmt: skip
    for kind in COMPOSITE_KINDS.values():
        lines += [f'### `type = "{kind.type_name}"` (`sparsekin.{kind.__name__}`)', "", *_paragraphs(kind),
                  f"- keys: {_keys(kind)}", ""]  # fmt: skip
    lines += ["## Laws (`law = { type = ... }`)", ""]
    for kind in BUILT_IN_LAWS:
        lines += [f'### `type = "{kind.type_name}"` (`sparsekin.{kind.__name__}`)', "", _description(kind), "",
                  f"- keys: {_keys(kind)}", ""]  # fmt: skip
    return "\n".join(lines).rstrip() + "\n"


def main(argv: list[str]) -> int:
    text = reference()
    if "--check" in argv:
        if not PAGE.exists() or PAGE.read_text(encoding="utf-8") != text:
            print(f"{PAGE} is stale: run python3 docs/make_element_reference.py", file=sys.stderr)
            return 1
        return 0
    PAGE.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
