"""The exception tree of upm: everything upm raises on purpose derives from :class:`UpmError`."""

from __future__ import annotations

__all__ = [
    "BoardError",
    "BoardTimeout",
    "CommandRefused",
    "ConvergenceError",
    "InternalError",
    "MissingExtraError",
    "ParameterError",
    "PlanWarning",
    "ProtocolError",
    "RankWarning",
    "ResonanceWarning",
    "ShapeError",
    "StrokeError",
    "UpmError",
    "UpmWarning",
    "VersionMismatch",
    "VisionError",
]


class UpmError(Exception):
    """Root of every error upm raises on purpose."""


class ParameterError(UpmError, ValueError):
    """A parameter is non-finite, outside its allowed range, or inconsistent with another one.

    The message names the parameter, what is allowed and what was received.
    """


class ShapeError(UpmError, ValueError):
    """Arrays whose shapes do not fit together; the message gives the expected shape."""


class ConvergenceError(UpmError, RuntimeError):
    """An iterative method did not reach its tolerance."""


class InternalError(UpmError, RuntimeError):
    """A bug in upm (a Rust panic caught at the boundary). Please report it with the message."""


class MissingExtraError(UpmError, ImportError):
    """An optional dependency is not installed; the message names the extra that brings it
    (``pip install 'upm[extra]'``)."""


class StrokeError(ParameterError):
    """A plate motion would move a plate corner further from home than the stroke allows."""


class UpmWarning(UserWarning):
    """Root of every warning upm issues: ``warnings.simplefilter("error", upm.UpmWarning)`` turns
    them all into errors."""


class RankWarning(UpmWarning):
    """A linear system is rank deficient: the result is a least-squares compromise, not exact."""


class PlanWarning(UpmWarning):
    """A plate motion program will not achieve its plan closely (the message says by how much)."""


class ResonanceWarning(UpmWarning):
    """The drive is too close to a resonance of the plate for velocity = integral of force / mass."""


class BoardError(UpmError):
    """The board link failed: a timeout, a protocol violation, a refused command (subclasses)."""


class VisionError(UpmError):
    """The camera frame is unusable or does not show what was looked for (the message says what)."""


class ProtocolError(BoardError):
    """A frame that is not a valid protocol message (the message says which check failed)."""


class BoardTimeout(BoardError):
    """The board did not answer in time (after the retries)."""


class PulseCut(BoardError):
    """A pulse the board accepted ended before its time: its watchdog tripped (the host fell
    silent) or it was stopped. Part of the pulse played; the parts are wherever it left them."""


class VersionMismatch(BoardError):
    """The board speaks another protocol version."""


class CommandRefused(BoardError):
    """The board answered NACK; ``code`` is the :class:`~upm.board.protocol.NackCode`."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code
