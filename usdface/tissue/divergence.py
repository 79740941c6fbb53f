"""What a simulation that blew up raises: :class:`DivergenceError`, with the time, step, frame
and likely cause (named by :class:`usdface.tissue.integrators.Simulator`'s diagnosis)."""
from __future__ import annotations

from ..errors import ComputeError

__all__ = ["DivergenceError"]


class DivergenceError(ComputeError):
    """The simulation blew up (NaN, runaway energy or displacement).

    Attributes
    ----------
    time : float
        Simulated time (s) when it was detected.
    step : int
        Integration step count.
    frame : int or None
        Animation frame, when known.
    cause : str
        The likely cause, in words.
    """

    def __init__(self, message: str, *, time: float, step: int, cause: str, frame: int | None = None):
        super().__init__(message)
        self.time, self.step, self.cause, self.frame = time, step, cause, frame

    def at_frame(self, frame: int) -> "DivergenceError":
        return DivergenceError(f"frame {frame}: {self.args[0]}", time=self.time, step=self.step, cause=self.cause,
                               frame=frame)
