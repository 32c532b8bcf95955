"""Reading and writing the TOML model file.

`load_model` translates a model file (the format described in ``docs/model-format.md``)
into a `Mechanism`; `save_model` writes a `Mechanism` back as such a file.  The reader only
translates: every element is built with the Python API (`Body`, `Revolute`, `Harmonic`,
...), which checks it.  Every mistake is reported as a one-line `ModelError`
``<file>: <element>: <what was expected>``, with the element spelt as in the file
(``joints[3].bodies[1]``, ``bodies.c7.origin``, ``drivers[0].law.amplitude``); mistakes
in the TOML syntax itself are located by line (``line 12, column 5``).

Which keys each element accepts is declared once, by its kind (``file_keys`` of the element
kinds of `sparsekin.model.elements`, of the laws, of `Body` and `Analysis`): the reader checks
the keys of every table against them and the writer writes the same keys.
"""

from __future__ import annotations

import ast
import dataclasses
import errno
import numbers
import os
import re
import stat
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import ModelError
from . import _validate
from .composites import COMPOSITE_KINDS, Parts
from .elements import DRIVER_KINDS, JOINT_KINDS, LOAD_KINDS
from .laws import BUILT_IN_LAWS, Spline
from .mechanism import Analysis, Body, Mechanism
from .shared_points import warn_unjoined_points
from .units import Cycle, OnCopies, Repeat, Step, Unit

__all__ = ["load_model", "save_model"]

#: The string that stands for the value of the driven quantity in the initial
#: configuration (``offset``, ``start``, polynomial ``c0``); None in Python.
INITIAL = "initial"


# --------------------------------------------------------------------------- the keys


@dataclass(frozen=True)
class _Spec:
    """The keys of one kind of element (its ``file_keys``) and how it is built.

    Attributes
    ----------
    kind : type
        The class of the element in the Python model; its fields carry the keys' names
        and its ``file_keys`` says which it accepts.
    build : callable or None
        Makes the element from the converted keys; `kind` itself when None.
    """

    kind: type
    build: Callable[..., Any] | None = None

    @property
    def required(self) -> tuple[str, ...]:
        return self.kind.file_keys.required

    @property
    def optional(self) -> tuple[str, ...]:
        return self.kind.file_keys.optional

    @property
    def forms(self) -> tuple[tuple[str, ...], ...]:
        return self.kind.file_keys.forms

    @property
    def keys(self) -> tuple[str, ...]:
        """Every key the element accepts, in the order they are listed and written."""
        return self.kind.file_keys.keys


def _spline(file: Spline | None = None, offset: float | None = 0.0, **samples: Any) -> Spline:
    """A `Spline` from ``times`` and ``values``, or the one already read from `file`, with `offset`."""
    if file is None:
        return Spline(**samples, offset=offset)
    return file if offset == 0.0 else dataclasses.replace(file, offset=offset)


_TOP_LEVEL_KEYS = ("name", "points", "bodies", "joints", "drivers", "loads", "composites", "gravity", "analysis",
                   "units", "repeat")  # fmt: skip
#: The sections of a unit: those of a model but `gravity`, `[analysis]` and nested units.
_UNIT_KEYS = ("points", "bodies", "joints", "drivers", "loads", "composites")
#: The keys of a `[[repeat]]` entry.
_REPEAT_KEYS = ("unit", "count", "prefix", "offset", "first", "vary", "boundary")
#: The keys of a unit's part's `copies = { i = …, j = … }` (the columns and rows that keep it).
_COPIES_KEYS = ("i", "j")
_BODY = _Spec(Body)
_JOINTS = {type_name: _Spec(kind) for type_name, kind in JOINT_KINDS.items()}
_DRIVERS = {type_name: _Spec(kind) for type_name, kind in DRIVER_KINDS.items()}
_LOADS = {type_name: _Spec(kind) for type_name, kind in LOAD_KINDS.items()}
_COMPOSITES = {type_name: _Spec(kind) for type_name, kind in COMPOSITE_KINDS.items()}
_LAWS = {kind.type_name: _Spec(kind, _spline if kind is Spline else None) for kind in BUILT_IN_LAWS}
_ANALYSIS = _Spec(Analysis)

#: What the columns of a spline CSV file are called in the errors of `Spline`.
_CSV_COLUMNS = {"times": 'column "t"', "values": 'column "value"'}


# --------------------------------------------------------------------------- reading


def load_model(path: str | os.PathLike) -> Mechanism:
    """Read a mechanism from a TOML model file.

    Parameters
    ----------
    path : str or path-like
        The model file.  Spline laws given as ``file = "law.csv"`` are read relative to
        the folder of this file.

    Returns
    -------
    Mechanism
        The mechanism the file describes; its name defaults to the file's stem.

    Raises
    ------
    ModelError
        For every mistake: an unreadable file, bad TOML, an unknown or missing key, a
        wrong value, an unknown body or point.  The message is one line,
        ``<path as given>: <element>: <what was expected>``.

    Warns
    -----
    UnjoinedPointWarning
        When a point is carried by bodies that no joint connects there
        (`sparsekin.model.shared_points`).
    """
    shown = os.fsdecode(path)
    try:
        document = _parse(Path(shown))
        reader = _Reader(folder=Path(shown).parent)
        mechanism = reader.mechanism(document, default_name=Path(shown).stem)
    except ModelError as error:
        raise _one_line(error if error.file else error.in_file(shown)) from None
    except RecursionError:  # a value nested deeper than the reader goes (issue 28)
        raise ModelError("a value nested too deep; expected a model file", file=shown) from None
    warn_unjoined_points(mechanism, source=shown)
    return mechanism


class _Reader:
    """Translates the parsed TOML document into model objects.

    Parameters
    ----------
    folder : Path
        Folder of the model file, against which referenced files are resolved.
    """

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        #: Keys whose TOML value is changed before it reaches the Python class.
        self.converters: dict[str, Callable[[Any, str], Any]] = {
            **{field: self.law for kind in DRIVER_KINDS.values() for field in kind.law_fields},
            "file": self.spline_file,
            "offset": _number_or_initial,
            "start": _number_or_initial,
            "coefficients": _coefficients,
            "axis": _axis,
            "value": self.load_value,
        }

    def mechanism(self, document: dict[str, Any], default_name: str) -> Mechanism:
        """The `Mechanism` of a whole document."""
        _check_keys(document, "", _TOP_LEVEL_KEYS)
        points, bodies, joints, drivers, loads, body_names, generated = self.parts(document, "")
        analysis = self.element(document.get("analysis", {}), "analysis", _ANALYSIS, "a table [analysis]")
        units = {
            name: self.unit(table, name)
            for name, table in _table(document.get("units", {}), "units", "tables [units.NAME]").items()
        }
        repeats = [
            self.repeat(table, f"repeat[{index}]", units)
            for index, table in enumerate(_array(document.get("repeat", []), "repeat"))
        ]
        try:
            return Mechanism(
                points=points,
                bodies=bodies,
                joints=joints,
                drivers=drivers,
                name=document.get("name", default_name),
                analysis=analysis,
                repeats=repeats,
                loads=loads,
                gravity=document.get("gravity", (0.0, 0.0)),
            )
        except ModelError as error:
            raise _body_by_name(_in_composite(error, generated), body_names) from None

    def parts(self, document: dict[str, Any], prefix: str):
        """Points, bodies, joints, drivers and loads of a model (`prefix` "") or a unit ("units.NAME.")."""
        body_tables = _table(document.get("bodies", {}), f"{prefix}bodies", f"tables [{prefix}bodies.NAME]")
        in_unit = bool(prefix)
        bodies = [
            self.placed(in_unit, table, f"{prefix}bodies.{name}",
                        lambda table, where, name=name: self.element(table, where, _BODY, f"a table [{where}]", name=name))
            for name, table in body_tables.items()
        ]  # fmt: skip
        joints, drivers, loads = (
            [self.placed(in_unit, table, f"{prefix}{kind}[{index}]",
                         lambda table, where, specs=specs, kind=kind: self.typed(table, where, specs,
                                                                                 f"a table [[{prefix}{kind}]]"))
             for index, table in enumerate(_array(document.get(kind, []), f"{prefix}{kind}"))]
            for kind, specs in (("joints", _JOINTS), ("drivers", _DRIVERS), ("loads", _LOADS))
        )  # fmt: skip
        points = _table(document.get("points", {}), f"{prefix}points", f"a table [{prefix}points] of name = [x, y]")
        composites = [
            self.typed(table, f"{prefix}composites[{index}]", _COMPOSITES, f"a table [[{prefix}composites]]")
            for index, table in enumerate(_array(document.get("composites", []), f"{prefix}composites"))
        ]
        generated = _expand_composites(composites, points, prefix, bodies, joints, drivers)
        return points, bodies, joints, drivers, loads, list(body_tables), generated

    def placed(self, in_unit: bool, table: object, where: str, build: Callable[[object, str], Any]) -> Any:
        """A part built by `build`; in a unit, wrapped in `OnCopies` when its table says
        ``copies = { i = …, j = … }``."""
        if not (in_unit and isinstance(table, dict) and "copies" in table):
            return build(table, where)
        element = build({key: value for key, value in table.items() if key != "copies"}, where)
        copies = _table(table["copies"], f"{where}.copies", "an inline table { i = I, j = J }")
        _check_keys(copies, f"{where}.copies", _COPIES_KEYS)
        try:
            return OnCopies(element, **{key: tuple(v) if isinstance(v, list) else v for key, v in copies.items()})
        except ModelError as error:
            raise error.within(where) from None

    def unit(self, value: object, name: str) -> Unit:
        """The `Unit` of a table ``[units.NAME]``."""
        where = f"units.{name}"
        table = _table(value, where, f"a table [{where}]")
        _check_keys(table, where, _UNIT_KEYS)
        points, bodies, joints, drivers, loads, body_names, generated = self.parts(table, f"{where}.")
        try:
            return Unit(name, points=points, bodies=bodies, joints=joints, drivers=drivers, loads=loads)
        except ModelError as error:
            raise _body_by_name(_in_composite(error, generated), body_names).within(where) from None

    def repeat(self, value: object, where: str, units: dict[str, Unit]) -> Repeat:
        """The `Repeat` of a table ``[[repeat]]``."""
        table = _table(value, where, "a table [[repeat]]")
        _check_keys(table, where, _REPEAT_KEYS)
        for key in ("unit", "count"):
            if key not in table:
                raise ModelError(f'missing key "{key}"', element=where)
        unit_name = _validate.name(table["unit"], f"{where}.unit")
        if unit_name not in units:
            known = _validate.known_list(list(units)) or "none: define [units.NAME]"
            raise ModelError(f'unknown unit "{unit_name}" (known: {known})', element=f"{where}.unit")
        vary = {}
        for path, variation in _table(table.get("vary", {}), f"{where}.vary", "a table of path = { step = … }").items():
            vary[path] = _variation(variation, f'{where}.vary."{path}"')
        count, offset = (_tuples(table.get(key, default)) for key, default in (("count", None), ("offset", (0.0, 0.0))))
        try:
            return Repeat(
                units[unit_name], count=count, prefix=table.get("prefix"), offset=offset,
                first=_table(table.get("first", {}), f"{where}.first", 'a table { "prev.NAME" = "BODY" }'), vary=vary,
                boundary=_table(table.get("boundary", {}), f"{where}.boundary", 'a table { "below.NAME" = "BODY" }'),
            )  # fmt: skip
        except ModelError as error:
            raise error.within(where) from None

    def element(self, value: object, element: str, spec: _Spec, expected: str, **fixed: Any) -> Any:
        """The element described by the table `value`.

        Parameters
        ----------
        value : object
            The TOML value, which must be a table.
        element : str
            Its location, for messages (``"bodies.c7"``).
        spec : _Spec
            The keys it accepts and the class it becomes.
        expected : str
            What `value` should be, for the message when it is not a table.
        **fixed
            Arguments that do not come from the table (a body's name).
        """
        return self._build(_table(value, element, expected), element, spec, spec.keys, fixed)

    def typed(self, value: object, element: str, specs: Mapping[str, _Spec], expected: str) -> Any:
        """The element described by the table `value`, whose key ``type`` selects one of `specs`."""
        table = _table(value, element, expected)
        if "type" not in table:
            raise ModelError(f'missing key "type" (expected one of: {", ".join(specs)})', element=element)
        spec = specs[_validate.choice(table["type"], f"{element}.type", tuple(specs))]
        return self._build(table, element, spec, ("type", *spec.keys), {})

    def _build(
        self,
        table: dict[str, Any],
        element: str,
        spec: _Spec,
        allowed: tuple[str, ...],
        fixed: dict[str, Any],
    ) -> Any:
        """Check the keys of `table`, convert their values and build the element of `spec`."""
        _check_keys(table, element, allowed)
        _check_required(table, element, spec)
        arguments = {
            key: self.converters.get(key, _unchanged)(value, f"{element}.{key}")
            for key, value in table.items()
            if key != "type" or "type" in spec.keys  # the kind's `type`, unless a field (the analysis')
        }
        try:
            return (spec.build or spec.kind)(**fixed, **arguments)
        except ModelError as error:
            raise error.within(element) from None

    def law(self, value: object, element: str) -> Any:
        """A driver's law, from its inline table."""
        return self.typed(value, element, _LAWS, 'an inline table { type = "...", ... }')

    def load_value(self, value: object, element: str) -> Any:
        """A load's value: a number, a law table, or a list of them (a force's components)."""
        if isinstance(value, dict):
            return self.law(value, element)
        if isinstance(value, list):
            return [self.law(item, f"{element}[{k}]") if isinstance(item, dict) else item for k, item in enumerate(value)]
        return value

    def spline_file(self, value: object, element: str) -> Spline:
        """The `Spline` through the samples of a CSV file with the header ``t,value``."""
        path = self.folder / _validate.name(value, element)
        shown = os.fspath(path)
        try:
            text = _read_text(path)
        except OSError as error:
            raise ModelError(f'cannot read "{shown}": {_os_reason(error)}', element=element) from None
        except ModelError as error:
            raise error.in_file(shown) from None
        times, values = _csv_samples(text, shown)
        try:
            return Spline(times, values)
        except ModelError as error:
            column = _CSV_COLUMNS.get(error.element, error.element)
            raise ModelError(error.reason, element=column, file=shown) from None


def _parse(path: Path) -> dict[str, Any]:
    """The TOML document in the file at `path`."""
    try:
        text = _read_text(path)
    except OSError as error:
        raise ModelError(f"cannot read the file: {_os_reason(error)}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise _toml_error(str(error), text) from None
    except RecursionError:
        raise ModelError("arrays or tables nested too deep to read; expected a model file") from None


#: The largest model (or spline CSV) file read, bytes: a model at scale repeats a unit.
MAX_FILE_BYTES = 256 * 2**20


def _read_text(path: Path) -> str:
    """The UTF-8 text of a file (a byte-order mark is allowed); raises OSError if unreadable,
    a `ModelError` if not a regular file (a device, a pipe) or larger than `MAX_FILE_BYTES`."""
    info = path.stat()
    if stat.S_ISDIR(info.st_mode):
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
    if not stat.S_ISREG(info.st_mode):
        raise ModelError("not a regular file (a device, a pipe or a socket); expected a file saved as UTF-8 text")
    data = b""
    if info.st_size <= MAX_FILE_BYTES:
        with open(path, "rb") as file:
            data = file.read(MAX_FILE_BYTES + 1)  # the file may have grown since
    if info.st_size > MAX_FILE_BYTES or len(data) > MAX_FILE_BYTES:
        raise ModelError(f"larger than {MAX_FILE_BYTES // 2**20} MB; expected a model file (repeat a unit for a "
                         "large model)")  # fmt: skip
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = data.count(b"\n", 0, error.start) + 1
        raise ModelError(
            f"not UTF-8 text (byte 0x{data[error.start]:02x}); expected a file saved as UTF-8",
            element=f"line {line}",
        ) from None


def _os_reason(error: OSError) -> str:
    return error.strerror or str(error)


_TOML_LOCATION = re.compile(r"(?P<what>.*) \(at (?P<where>line (?P<line>\d+), column \d+|end of document)\)")


def _toml_error(message: str, text: str) -> ModelError:
    """A `ModelError` for the `TOMLDecodeError` `message`, located by line and column."""
    match = _TOML_LOCATION.fullmatch(message)
    if match is None:
        return ModelError(f"invalid TOML: {message}")
    lines = text.splitlines()
    line_number = int(match["line"]) if match["line"] else 0
    line = lines[line_number - 1] if 0 < line_number <= len(lines) else ""
    where = "end of file" if match["where"] == "end of document" else match["where"]
    return ModelError(_toml_reason(match["what"], line), element=where)


def _toml_reason(what: str, line: str) -> str:
    """What a TOML syntax error means, saying "duplicate" for TOML's duplicate errors."""
    if declared := re.fullmatch(r"Cannot declare (\(.*\)) twice", what):
        table = ".".join(_key(part) for part in ast.literal_eval(declared[1]))
        return f"duplicate table [{table}]: each table may be declared only once"
    if inline := re.fullmatch(r"Duplicate inline table key '(.*)'", what):
        return f'duplicate key "{inline[1]}" in an inline table'
    if what == "Cannot overwrite a value":
        key = re.match(r"\s*[\"']?([^=#\[\"']+?)[\"']?\s*=", line)
        if key:
            return f'duplicate key "{key[1]}": each key may be given only once in a table'
        return "a key or table is defined twice"
    return f"invalid TOML: {what}"


def _check_keys(table: Mapping[str, Any], element: str, allowed: tuple[str, ...]) -> None:
    for key in table:
        if key not in allowed:
            raise ModelError(f'unknown key "{key}" (expected one of: {", ".join(allowed)})', element=element)


def _check_required(table: Mapping[str, Any], element: str, spec: _Spec) -> None:
    """Raise if a required key, or a whole alternative form of keys, is missing."""
    missing = [key for key in spec.required if key not in table]
    if spec.forms and not missing:
        given = [form for form in spec.forms if any(key in table for key in form)]
        alternatives = " or ".join(_keys_phrase(form) for form in spec.forms)
        if len(given) > 1:
            raise ModelError(f"give either {alternatives}, not both", element=element)
        if not given:
            raise ModelError(f"missing {alternatives}", element=element)
        missing = [key for key in given[0] if key not in table]
    if missing:
        raise ModelError(f"missing {_keys_phrase(missing)}", element=element)


def _keys_phrase(keys: tuple[str, ...] | list[str]) -> str:
    """``key "at"``, ``keys "at" and "direction"``."""
    quoted = [f'"{key}"' for key in keys]
    if len(quoted) == 1:
        return f"key {quoted[0]}"
    return f"keys {', '.join(quoted[:-1])} and {quoted[-1]}"


def _table(value: object, element: str, expected: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ModelError(f"expected {expected}, got {_kind(value)}", element=element)
    return value


def _array(value: object, element: str) -> list[Any]:
    if not isinstance(value, list):
        raise ModelError(f"expected an array of tables [[{element}]], got {_kind(value)}", element=element)
    return value


def _kind(value: object) -> str:
    """The TOML type of a parsed value, for messages: ``an array``, ``the number 5``."""
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, (int, float)):
        return f"the number {value!r}"
    return f"a date or time ({value})"


def _unchanged(value: object, element: str) -> object:
    return value


def _number_or_initial(value: object, element: str) -> object:
    """None for the string "initial"; any other value is left for the model to check."""
    if isinstance(value, str):
        if value != INITIAL:
            raise ModelError(f'expected a number or "{INITIAL}", got {value!r}', element=element)
        return None
    return value


def _coefficients(value: object, element: str) -> object:
    """Polynomial coefficients, with a first coefficient "initial" made None."""
    if not isinstance(value, list):
        raise ModelError(f"expected an array of numbers [c0, c1, ...], got {_kind(value)}", element=element)
    if not value:
        return value
    return [_number_or_initial(value[0], f"{element}[0]"), *value[1:]]


def _axis(value: object, element: str) -> object:
    """A translational joint's axis, if it is an array; a table is refused in TOML's words."""
    if not isinstance(value, list):
        raise ModelError(f"expected two points [P, Q], got {_kind(value)}", element=element)
    return value


def _variation(value: object, element: str) -> Step | Cycle:
    """``{ step = x }`` or ``{ cycle = [v0, v1, ...] }``."""
    table = _table(value, element, "{ step = … } or { cycle = […] }")
    if set(table) == {"step"}:
        return Step(_tuples(table["step"]))
    if set(table) == {"cycle"}:
        values = table["cycle"]
        if not isinstance(values, list):
            raise ModelError(f"expected a list of values, got {_kind(values)}", element=f"{element}.cycle")
        try:
            return Cycle(tuple(tuple(v) if isinstance(v, list) else v for v in values))
        except ModelError as error:
            raise error.within(element) from None
    raise ModelError(f"expected {{ step = … }} or {{ cycle = […] }}, got keys {', '.join(table) or 'none'}",
                     element=element)  # fmt: skip


def _flat(value: object) -> list:
    """The numbers of a nested tuple, in order."""
    return [x for item in value for x in _flat(item)] if isinstance(value, (tuple, list)) else [value]


def _tuples(value: object) -> object:
    """TOML arrays (nested ones too) as tuples, as the model's pairs and vectors are."""
    return tuple(_tuples(item) for item in value) if isinstance(value, list) else value


def _csv_samples(text: str, shown: str) -> tuple[list[float], list[float]]:
    """The columns t and value of a spline CSV file (a header line, then one sample a line)."""
    lines = text.splitlines()
    header = lines[0] if lines else ""
    if [cell.strip() for cell in header.split(",")] != ["t", "value"]:
        raise ModelError(f'expected the header line "t,value", got {header!r}', element="line 1", file=shown)
    times: list[float] = []
    values: list[float] = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        cells = line.split(",")
        if len(cells) != 2:
            raise ModelError(
                f"expected two numbers t,value, got {line!r}", element=f"line {number}", file=shown
            )
        times.append(_csv_number(cells[0], f'line {number}, column "t"', shown))
        values.append(_csv_number(cells[1], f'line {number}, column "value"', shown))
    return times, values


def _csv_number(cell: str, element: str, shown: str) -> float:
    text = cell.strip()
    try:
        value: object = float(text)
    except ValueError:
        value = text  # not a number: let the check say so
    try:
        return _validate.finite_float(value, element)
    except ModelError as error:
        raise error.in_file(shown) from None


def _expand_composites(composites, points, prefix: str, bodies: list, joints: list, drivers: list) -> dict[str, tuple]:
    """Append the parts of every composite to `bodies`, `joints` and `drivers`; returns,
    for each part, its label in the model (``joints[7]``) → ``(composite's label, part)``."""
    generated: dict[str, tuple[str, str]] = {}
    for index, composite in enumerate(composites):
        where = f"{prefix}composites[{index}]"

        def position(reference, composite=composite):
            if not isinstance(reference, str):
                return reference
            try:
                return _validate.pair(points[reference], f"{prefix}points.{reference}")
            except KeyError:
                raise ModelError(f'unknown point "{reference}": the centre of mass of a {composite.type_name} '
                                 f"needs its pins in [{prefix}points] or as [x, y]") from None  # fmt: skip

        try:
            parts: Parts = composite.expand(position)
        except ModelError as error:
            raise error.within(where) from None
        for kind, own, added in zip(("bodies", "joints", "drivers"), (bodies, joints, drivers), parts):
            for element in added:
                generated[f"{kind}[{len(own)}]"] = (where, f'{kind[:-1] if kind != "bodies" else "body"} "{element.name}"')
                own.append(element)
    return generated


def _in_composite(error: ModelError, generated: dict[str, tuple]) -> ModelError:
    """`error` located at the composite whose part it is about, if it is about a part."""
    match = re.match(r"(bodies|joints|drivers)\[\d+\]", error.element)
    if match is None or match[0] not in generated:
        return error
    where, part = generated[match[0]]
    return ModelError(f"{error.reason} (in its {part}{error.element[match.end():]})", element=where, file=error.file)


def _body_by_name(error: ModelError, body_names: list[str]) -> ModelError:
    """`error` with ``bodies[k]`` (the model's spelling) replaced by ``bodies.NAME`` (the file's)."""
    match = re.match(r"bodies\[(\d+)\](\.name$)?", error.element)
    if match is None:
        return error
    element = f"bodies.{body_names[int(match[1])]}{error.element[match.end():]}"
    return ModelError(error.reason, element=element, file=error.file)


_LINE_BREAKS = re.compile("[\x00-\x1f\x7f\x85\u2028\u2029]")


def _one_line(error: ModelError) -> ModelError:
    """`error` with control characters (newlines in a name, say) shown as escapes."""

    def escaped(text: str | None) -> str | None:
        if not text:
            return text
        return _LINE_BREAKS.sub(lambda match: match[0].encode("unicode_escape").decode("ascii"), text)

    return ModelError(escaped(error.reason), element=escaped(error.element), file=escaped(error.file))


# --------------------------------------------------------------------------- writing


def save_model(mechanism: Mechanism, path: str | os.PathLike) -> None:
    """Write a mechanism as a TOML model file that `load_model` reads back equal.

    Numbers are written with `repr`, so they are read back exactly; spline laws are
    written inline (``times``, ``values``).  Nothing is written if the mechanism cannot
    be.

    Parameters
    ----------
    mechanism : Mechanism
        The mechanism to write.
    path : str or path-like
        The file to create or replace (UTF-8).

    Raises
    ------
    ModelError
        If a driver's law is not one of the built-in laws (harmonic, linear,
        polynomial, spline): such an object has no spelling in the file.
    """
    if not isinstance(mechanism, Mechanism):
        raise TypeError(f"`mechanism` must be a Mechanism, got {type(mechanism).__name__}")
    text = _model_text(mechanism)
    with open(path, "w", encoding="utf-8", newline="\n") as file:
        file.write(text)


def _model_text(mechanism: Mechanism) -> str:
    """The TOML text of `mechanism`, one blank-line-separated block per table.

    Repeated units are written as units and ``[[repeat]]`` entries, never copy by copy.
    """
    blocks = [f"name = {_string(mechanism.name)}"]
    if mechanism.gravity != (0.0, 0.0):
        blocks[0] += f"\ngravity = {_value(mechanism.gravity, 'gravity')}"
    kinds = ("bodies", "joints", "drivers", "loads")
    blocks += _parts_text(mechanism.own("points"), *(mechanism.own(kind) for kind in kinds), "")
    analysis = _pairs(mechanism.analysis, _ANALYSIS, "analysis")
    if analysis:
        blocks.append(_block("[analysis]", analysis))
    units: dict[str, Unit] = {}
    for index, repeat in enumerate(mechanism.repeats):
        if units.setdefault(repeat.unit.name, repeat.unit) is not repeat.unit:
            raise ModelError(f'two different units are called "{repeat.unit.name}"', element=f"repeat[{index}].unit")
    for name, unit in units.items():
        blocks += _parts_text(unit.points, unit.bodies, unit.joints, unit.drivers, unit.loads, f"units.{_key(name)}.",
                              unit.only)  # fmt: skip
    for repeat in mechanism.repeats:
        pairs = [("unit", _string(repeat.unit.name)), ("count", _value(repeat.count, "repeat.count")),
                 ("prefix", _string(repeat.prefix))]  # fmt: skip
        if any(value != 0.0 for value in _flat(repeat.offset)):
            pairs.append(("offset", _value(repeat.offset, "repeat.offset")))
        for attachment in ("first", "boundary"):
            if getattr(repeat, attachment):
                names = getattr(repeat, attachment).items()
                pairs.append((attachment, "{ " + ", ".join(f"{_key(k)} = {_string(v)}" for k, v in names) + " }"))
        blocks.append(_block("[[repeat]]", pairs))
        if repeat.vary:  # a sub-table of this entry, one variation a line (long cycles: one value a line)
            blocks.append("\n".join(["[repeat.vary]", *(_variation_line(path, v) for path, v in repeat.vary.items())]))
    return "\n\n".join(blocks) + "\n"


def _parts_text(points, bodies, joints, drivers, loads, prefix: str, only=None) -> list[str]:
    """The blocks of the points, bodies, joints, drivers and loads of a model or a unit
    (`only`: a unit's parts restricted to some copies, written ``copies = { i = …, j = … }``)."""
    only = only or {}

    def copies(kind: str, index: int) -> list[tuple[str, str]]:
        restriction = only.get((kind, index))
        if restriction is None:
            return []
        bounds = [(axis, bound[0] if bound[0] == bound[1] else list(bound))
                  for axis, bound in zip("ij", restriction) if bound is not None]  # fmt: skip
        return [("copies", "{ " + ", ".join(f"{axis} = {_value(b, 'copies')}" for axis, b in bounds) + " }")]

    blocks = []
    if points:
        blocks.append(_block(f"[{prefix}points]", [(name, _value(xy, f"points.{name}")) for name, xy in points.items()]))
    for index, body in enumerate(bodies):
        blocks.append(_block(f"[{prefix}bodies.{_key(body.name)}]",
                             _pairs(body, _BODY, f"bodies.{body.name}") + copies("bodies", index)))  # fmt: skip
    for kind, specs, items in (("joints", _JOINTS, joints), ("drivers", _DRIVERS, drivers), ("loads", _LOADS, loads)):
        for index, item in enumerate(items):
            element = f"{prefix}{kind}[{index}]"
            type_name = _type_name(item, specs, element)
            blocks.append(_block(f"[[{prefix}{kind}]]", _pairs(item, specs[type_name], element, type_name)
                                 + copies(kind, index)))  # fmt: skip
    return blocks


def _variation_line(path: str, variation: Step | Cycle) -> str:
    """``"points.M".step = [0.1, 0]`` or a cycle, its values one a line when there are many."""
    if isinstance(variation, Step):
        return f"{_key(path)}.step = {_value(variation.value, 'step')}"
    values = [_value(value, "cycle") for value in variation.values]
    if len(values) <= 4:
        return f"{_key(path)}.cycle = [{', '.join(values)}]"
    return f"{_key(path)}.cycle = [\n" + "".join(f"    {value},\n" for value in values) + "]"


def _block(header: str, pairs: list[tuple[str, str]]) -> str:
    return "\n".join([header, *(f"{_key(key)} = {value}" for key, value in pairs)])


def _pairs(item: object, spec: _Spec, element: str, type_name: str | None = None) -> list[tuple[str, str]]:
    """``(key, TOML value)`` of the fields of `item` that differ from their defaults.

    ``name`` comes first and ``type`` second, as in the examples of the format.
    """
    defaults = {field.name: field.default for field in dataclasses.fields(item)}
    values = {"type": type_name, **{key: getattr(item, key, None) for key in spec.keys}}
    pairs = []
    for key in sorted(values, key=lambda key: (key != "name", key != "type")):
        value = values[key]
        if (value is None and defaults.get(key) is None) or (key in spec.optional and value == defaults.get(key)):
            continue  # (None where the default is a number is written "initial": a spline's offset)
        pairs.append((key, _value(value, f"{element}.{key}")))
    return pairs


def _type_name(item: object, specs: Mapping[str, _Spec], element: str) -> str:
    """The ``type`` of `item` in the file; a `ModelError` if it has none."""
    for type_name, spec in specs.items():
        if type(item) is spec.kind:
            return type_name
    raise ModelError(
        f"cannot write a {type(item).__name__} to a model file: expected one of the built-in "
        f"types {', '.join(specs)}",
        element=element,
    )


def _value(value: object, element: str) -> str:
    """The TOML spelling of a field's value; None inside a list is the string "initial"."""
    if isinstance(value, str):
        return _string(value)
    if value is None:
        return _string(INITIAL)
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        return repr(float(value))
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_value(item, f"{element}[{index}]") for index, item in enumerate(value)) + "]"
    type_name = _type_name(value, _LAWS, element)
    pairs = _pairs(value, _LAWS[type_name], element, type_name)
    return "{ " + ", ".join(f"{_key(key)} = {text}" for key, text in pairs) + " }"


_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")
_STRING_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}
_NEEDS_ESCAPE = re.compile('["\\\\\x00-\x1f\x7f]')


def _key(name: str) -> str:
    """`name` as a TOML key: bare when it can be, quoted otherwise."""
    return name if _BARE_KEY.fullmatch(name) else _string(name)


def _string(text: str) -> str:
    """`text` as a TOML basic string."""
    escaped = _NEEDS_ESCAPE.sub(lambda match: _STRING_ESCAPES.get(match[0], f"\\u{ord(match[0]):04x}"), text)
    return f'"{escaped}"'
