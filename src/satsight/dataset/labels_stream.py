"""labels.json read as a stream: its frames one at a time, then its header.

The labels.json of a 10^6-frame dataset is about 8 GB, far more than a reader can parse at
once. ``LabelsStream`` parses it through a buffer of about a megabyte, one JSON value at a
time (a frame, or one entry of the header), so that memory holds one frame, not all. It
accepts any JSON layout, not only the one ``satsight`` writes, and reports errors as
``json.loads`` would (message, line, column and character of the document).
"""

from __future__ import annotations

import codecs
import json
import re
from collections.abc import Iterator
from pathlib import Path

#: Bytes read at a time.
CHUNK_BYTES = 1 << 20
#: Characters one value may span (a frame, or one header entry): a bound on the buffer.
MAX_VALUE_CHARS = 1 << 28
_WHITESPACE = re.compile(r"[ \t\n\r]*")
_DECODER = json.JSONDecoder()
# A decoding error this close to the buffer's end may be a value cut by the buffer.
_CUT_MARGIN_CHARS = 8
_VALUE_STARTS = '[{"-0123456789tfn'


class LabelsStreamError(Exception):
    """labels.json cannot be read as a JSON object with a frames list (message for users)."""


class _Text:
    """The decoded text of a file, read chunk by chunk; ``pos`` indexes ``buf``.

    Consumed text is dropped on each refill; ``base`` characters and ``lines`` newlines
    lie before ``buf`` (for error positions), the last of them ending at ``line_end``.
    """

    def __init__(self, stream, digest=None):
        self.stream = stream
        self.digest = digest
        self.decoder = codecs.getincrementaldecoder("utf-8")()
        self.buf = ""
        self.pos = 0
        self.base = 0
        self.lines = 0
        self.line_end = -1
        self.eof = False

    def more(self) -> bool:
        """Read another chunk (as large as the text held, so a long value takes few reads);
        False at the end of the file (``buf`` is then unchanged)."""
        if self.eof:
            return False
        data = self.stream.read(max(CHUNK_BYTES, len(self.buf) - self.pos))
        if self.digest is not None:
            self.digest.update(data)
        if not data:
            self.eof = True
            self.decoder.decode(b"", final=True)  # raises on a cut UTF-8 sequence
            return False
        if self.pos:
            dropped = self.buf[: self.pos]
            newlines = dropped.count("\n")
            if newlines:
                self.lines += newlines
                self.line_end = self.base + dropped.rfind("\n")
            self.base += self.pos
            self.buf = self.buf[self.pos :]
            self.pos = 0
        if len(self.buf) > MAX_VALUE_CHARS:
            raise self.error(f"a value longer than {MAX_VALUE_CHARS} characters", 0)
        self.buf += self.decoder.decode(data)
        return True

    def error(self, message: str, pos: int) -> ValueError:
        """A ValueError worded as ``json.JSONDecodeError``'s, at ``buf[pos]``."""
        line = self.lines + self.buf.count("\n", 0, pos) + 1
        newline = self.buf.rfind("\n", 0, pos)
        line_end = self.base + newline if newline >= 0 else self.line_end
        char = self.base + pos
        return ValueError(f"{message}: line {line} column {char - line_end} (char {char})")

    def skip_whitespace(self) -> None:
        while True:
            self.pos = _WHITESPACE.match(self.buf, self.pos).end()
            if self.pos < len(self.buf) or not self.more():
                return

    def peek(self) -> str:
        """The next character after whitespace ('' at the end of the file)."""
        self.skip_whitespace()
        return self.buf[self.pos] if self.pos < len(self.buf) else ""

    def take(self, char: str) -> bool:
        """Consume ``char`` if it comes next (after whitespace)."""
        if self.peek() == char:
            self.pos += 1
            return True
        return False

    def value(self):
        """The next JSON value, read whole (refilling the buffer while it is cut)."""
        self.skip_whitespace()
        while True:
            try:
                value, end = _DECODER.raw_decode(self.buf, self.pos)
            except json.JSONDecodeError as error:
                cut = error.msg.startswith("Unterminated string") or (
                    error.pos >= len(self.buf) - _CUT_MARGIN_CHARS
                )
                if cut and self.more():
                    continue
                raise self.error(error.msg, error.pos) from None
            if end == len(self.buf) and self.more():
                continue  # a number or literal may go on in the next chunk
            self.pos = end
            return value


class LabelsStream:
    """A labels.json file: ``frames()`` yields its frames; ``header`` is then the rest.

    header: the document without ``frames``, set once ``frames()`` has read the whole file
    (None before). digest: a hashlib object updated with every byte read (the whole file's
    once ``frames()`` is exhausted). Errors raise ``LabelsStreamError`` with the messages
    of a whole-file read: the file missing, not readable JSON, not an object, no
    ``frames`` key, or ``frames`` not a list.
    """

    def __init__(self, path: Path, digest=None):
        self.path = Path(path)
        self.digest = digest
        self.header: dict | None = None

    def frames(self) -> Iterator:
        try:
            stream = open(self.path, "rb")
        except FileNotFoundError:
            raise LabelsStreamError(f"{self.path} is missing") from None
        except OSError as error:
            raise LabelsStreamError(f"{self.path} is not readable JSON: {error}") from None
        with stream:
            text = _Text(stream, self.digest)
            try:
                yield from self._document(text)
            except ValueError as error:  # JSON or UTF-8 decoding
                raise LabelsStreamError(f"{self.path} is not readable JSON: {error}") from None
            except OSError as error:
                raise LabelsStreamError(f"{self.path} is not readable JSON: {error}") from None

    def _document(self, text: _Text) -> Iterator:
        first = text.peek()
        if first != "{":
            if first and first in _VALUE_STARTS:
                raise LabelsStreamError(f"{self.path} does not hold a JSON object")
            text.value()  # raises the decoder's error
            raise LabelsStreamError(f"{self.path} does not hold a JSON object")
        text.pos += 1
        header: dict = {}
        has_frames = False
        if not text.take("}"):
            while True:
                if text.peek() != '"':
                    raise text.error("Expecting property name enclosed in double quotes", text.pos)
                key = text.value()
                if not text.take(":"):
                    raise text.error("Expecting ':' delimiter", text.pos)
                if key == "frames":
                    has_frames = True
                    if text.peek() != "[":
                        raise LabelsStreamError(f"frames is a {type(text.value()).__name__}")
                    yield from self._array(text)
                else:
                    header[key] = text.value()
                if text.take(","):
                    continue
                if text.take("}"):
                    break
                raise text.error("Expecting ',' delimiter", text.pos)
        if text.peek():
            raise text.error("Extra data", text.pos)
        if not has_frames:
            raise LabelsStreamError(repr("frames"))
        self.header = header

    @staticmethod
    def _array(text: _Text) -> Iterator:
        text.pos += 1  # "["
        if text.take("]"):
            return
        while True:
            yield text.value()
            if text.take(","):
                continue
            if text.take("]"):
                return
            raise text.error("Expecting ',' delimiter", text.pos)
