"""Errors raised at the library's boundary. Each carries a one-line message naming the problem."""


class IMMError(Exception):
    """Base class: the CLI prints `str(err)` as one line instead of a traceback."""


class DataFormatError(IMMError, ValueError):
    """A data file is malformed (names the file and, where it applies, the line)."""


class CheckpointError(IMMError, ValueError):
    """A checkpoint is missing, corrupt or does not match the model/data."""


class LabelError(IMMError, ValueError):
    """A label vector has the wrong length, unknown class names or non-finite values."""


class TrainingError(IMMError, RuntimeError):
    """Training cannot go on (a loss that is not finite, names the epoch or step)."""


def printable(text: str) -> str:
    """`text` safe to print as one line on a terminal: control characters (a newline or an escape sequence in a file
    name) are shown escaped as Python writes them (\\n, \\x1b), never acted on."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii") for c in text)


def quoted(value, limit: int = 40) -> str:
    """A user's value in a message: repr-quoted (control characters escaped), cut to about `limit` characters."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 4] + "...'"
