"""Messages for a scenario that fails validation: pydantic's errors turned into one line
per bad key, naming the key, the problem and the value given."""

from __future__ import annotations

from pydantic import ValidationError

_MAX_LISTED_ERRORS = 50  # a file of 100 000 wrong values gets a page of them, not a flood
_MAX_SHOWN_CHARS = 200  # a value shown after "got" is cut to this many characters


def _shown(value: object) -> str:
    """A value as shown after "got" in a message: its repr, cut to _MAX_SHOWN_CHARS."""
    text = repr(value)
    return text if len(text) <= _MAX_SHOWN_CHARS else text[: _MAX_SHOWN_CHARS - 3] + "..."


def format_validation_error(error: ValidationError, source: str) -> str:
    """A scenario's validation errors, one line each: where (the key's dotted path), what
    is wrong, and the value given (cut to a readable length)."""
    lines = [f"{source}: the scenario is not valid:"]
    items = error.errors()
    for item in items[:_MAX_LISTED_ERRORS]:
        where = ".".join(str(p) for p in item["loc"]) or "(top level)"
        message = item["msg"].removeprefix("Value error, ")
        if item["type"] == "extra_forbidden":
            message = "unknown key (check the spelling; see examples for valid keys)"
        elif item["type"] == "missing":
            message = "required key is missing"
        got = item.get("input")
        suffix = (
            ""
            if item["type"] in ("missing", "extra_forbidden") or isinstance(got, dict)
            else f" (got {_shown(got)})"
        )
        lines.append(f"  - {where}: {message}{suffix}")
    if len(items) > _MAX_LISTED_ERRORS:
        lines.append(f"  ... and {len(items) - _MAX_LISTED_ERRORS} more")
    return "\n".join(lines)
