"""Type checks of the JSON lines the package reads back (run records, blind cases, tracking
steps, coverage records, best-known entries).

A schema maps a field to its :class:`Field`: the JSON types it may hold and whether it must be
there.  Types are strict: ``true`` is not a number, ``1`` is not a boolean and ``"no"`` is
not ``false`` (a hand-edited ``"replace": "no"`` read as true would change a score), so one
wrong field stops the reading with one line naming the file, the line and the field.
Fields a schema does not name are not checked (records carry free-form extras).  A field
may also type its members (``req("dict", values="number|null")``: every value of the object,
or item of the list): a hand-edited ``"estimate": {"Na": "abc"}`` is refused as
``field 'estimate.Na'``, not met later as a traceback.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

#: JSON type names -> the Python types ``json.loads`` makes of them
_TYPES: dict[str, tuple[type, ...]] = {
    "bool": (bool,), "int": (int,), "number": (int, float), "str": (str,),
    "list": (list,), "dict": (dict,), "null": (type(None),),
}


class SchemaError(ValueError):
    """A JSON line whose fields are missing or of the wrong type."""


@dataclass(frozen=True)
class Field:
    """What one field may hold: JSON type names (``"int|null"``) and whether it is required."""

    types: str
    required: bool = True
    values: str | None = None   # JSON types of every member (dict values, list items)

    def accepts(self, value: object) -> bool:
        return _is(value, self.types)

    def bad_member(self, value: object) -> tuple[object, object] | None:
        """The first member (its key or index, and itself) not of :attr:`values`."""
        if self.values is None or not isinstance(value, dict | list):
            return None
        items = value.items() if isinstance(value, dict) else enumerate(value)
        return next(((k, v) for k, v in items if not _is(v, self.values)), None)


def _is(value: object, types: str) -> bool:
    """Whether ``value`` is of one of the JSON ``types`` (``"int|null"``)."""
    for name in types.split("|"):
        if name in ("int", "number") and isinstance(value, bool):
            continue   # a boolean is an int to Python, not a count to us
        if isinstance(value, _TYPES[name]):
            return True
    return False


Schema = Mapping[str, Field]
#: A schema, or a function choosing one by the record (e.g. an error record's own schema).
SchemaLike = Schema | Callable[[dict], Schema]


def req(types: str, values: str | None = None) -> Field:
    """A required field of these JSON types (``values``: of its members)."""
    return Field(types, True, values)


def opt(types: str, values: str | None = None) -> Field:
    """An optional field of these JSON types (``values``: of its members)."""
    return Field(types, False, values)


def check(record: object, schema: SchemaLike, where: str) -> dict:
    """``record`` if it is a JSON object matching ``schema``; :class:`SchemaError` naming
    ``where`` (file and line) and the first bad field otherwise."""
    if not isinstance(record, dict):
        raise SchemaError(f"{where}: expected a JSON object, got {type(record).__name__}")
    fields = schema(record) if callable(schema) else schema
    for name, spec in fields.items():
        if name not in record:
            if spec.required:
                raise SchemaError(f"{where}: field {name!r} is missing")
            continue
        value = record[name]
        if not spec.accepts(value):
            shown = repr(value)
            shown = shown if len(shown) <= 40 else shown[:37] + "..."
            raise SchemaError(f"{where}: field {name!r} must be {spec.types.replace('|', ' or ')}"
                              f", got {shown}")
        member = spec.bad_member(value)
        if member is not None:
            shown = repr(member[1])
            shown = shown if len(shown) <= 40 else shown[:37] + "..."
            raise SchemaError(f"{where}: field '{name}.{member[0]}' must be "
                              f"{str(spec.values).replace('|', ' or ')}, got {shown}")
    return record


#: our type names -> JSON Schema's
JSON_SCHEMA_TYPES = {"bool": "boolean", "int": "integer", "number": "number", "str": "string",
                     "list": "array", "dict": "object", "null": "null"}
JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"


def json_schema(fields: Schema) -> dict:
    """``fields`` as a JSON Schema object (draft 2020-12): each field's types, the required
    ones listed, other fields allowed (records carry free-form extras), as :func:`check`
    reads them.  (One difference is JSON Schema's: it counts ``1.0`` as an integer, which
    ``json.loads`` reads as a float and :func:`check` refuses.)"""
    props = {}
    for name, spec in fields.items():
        types = [JSON_SCHEMA_TYPES[t] for t in spec.types.split("|")]
        props[name] = {"type": types[0] if len(types) == 1 else types}
    return {"type": "object", "required": [n for n, s in fields.items() if s.required],
            "properties": props}


def json_schema_document(title: str, description: str, *alternatives: Schema) -> dict:
    """A JSON Schema file for one kind of line or file: ``title``, ``description`` and the
    object schema of each alternative (one: that schema; several, e.g. a step line or its
    error line: ``anyOf``)."""
    objs = [json_schema(a) for a in alternatives]
    body = objs[0] if len(objs) == 1 else {"anyOf": objs}
    return {"$schema": JSON_SCHEMA_DIALECT, "title": title, "description": description, **body}
