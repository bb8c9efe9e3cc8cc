"""Errors a user can act on. The CLI prints them as one line and exits non-zero."""


class FenestraError(Exception):
    """Base class: a clear, one-line problem with the user's input (file, value, config)."""


class SceneError(FenestraError):
    """An IFC file that is missing, unreadable, corrupt, or has no usable windows."""


class PipelineError(FenestraError):
    """Bad input to the reconstruction pipeline (photo, K, masks)."""


class DatasetError(FenestraError, ValueError):
    """A file or folder that does not follow the data contract (the message names it): also an
    image or instance map that is missing or cannot be decoded (fenestra.images)."""


MAX_SHOWN_CHARS = 200  # a value quoted in an error message: at most this many characters
MAX_LINE_CHARS = 2000  # an error line the CLI prints: at most this many characters


def bounded(value: object, limit: int = MAX_SHOWN_CHARS) -> str:
    """``value`` as text (an exception: its message) on one line, cut to ``limit`` characters with
    the length it had: what an error message quotes of a user's value (a list of 50000
    coefficients is never echoed whole)."""
    text = " ".join(str(value).split())
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def one_line(e: BaseException) -> str:
    """The error's message on one line, at most MAX_LINE_CHARS characters (without a message: its
    class name): how the CLI prints it."""
    return bounded(e, MAX_LINE_CHARS) or type(e).__name__
