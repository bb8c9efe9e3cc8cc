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


def one_line(e: BaseException) -> str:
    """The error's message on one line (without a message: its class name): how the CLI prints it."""
    return " ".join(str(e).split()) or type(e).__name__
