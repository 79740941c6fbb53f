"""Driving a Simulator through a timeline, frame by frame, and the controls of an animation."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterator

import numpy as np

from .expressions import Timeline

if TYPE_CHECKING:  # the simulator (and its numba kernels) loads with the first simulation, not here
    from .integrators import Simulator


def animate(sim: Simulator, timeline: Timeline, *, frames=None, settle_first: bool = True,
            max_settle: float = 3.0) -> Iterator[tuple[float, np.ndarray]]:
    """Simulate a timeline and yield ``(frame, skin points (N, 3))`` for each frame.

    The first frame's controls are applied and (``settle_first``) the tissue brought to
    equilibrium; between frames the controls move linearly over ``1 / rate`` seconds, integrated
    in steps of at most ``sim.dt``.

    Raises
    ------
    DivergenceError
        With the frame at which the simulation blew up.
    """
    from .divergence import DivergenceError

    names = sim.muscles.names
    frames = timeline.frame_numbers() if frames is None else np.asarray(frames, dtype=np.float64)
    has_jaw = sim.jaw is not None
    timeline.check_names(names, has_jaw=has_jaw)
    prev = None
    for fr in frames:
        a, jaw = timeline.evaluate(fr, names)
        try:
            if prev is None:
                sim.set_controls(a, jaw=jaw if has_jaw else None)
                if settle_first and (a.any() or jaw > 0):
                    sim.run_to_equilibrium(max_time=max_settle)
            else:
                sim.advance((fr - prev) / timeline.rate, contraction=a, jaw=jaw if has_jaw else None)
        except DivergenceError as e:
            raise e.at_frame(int(round(fr))) from None
        prev = fr
        yield float(fr), sim.skin()


@dataclass(frozen=True)
class ControlSamples:
    """The controls of a simulated animation at its frames: what an animation layer records
    beside the skin points (:func:`usdface.usd.muscle_layer.write_tissue_animation_layer`).

    Attributes
    ----------
    time_codes : ndarray (F,) float64
        Time code of each frame.
    rate : float
        Time codes per second.
    muscle_names : tuple of str, length M
    contractions : ndarray (F, M) float64
        Contraction of each muscle per frame, in [0, 1].
    jaw : ndarray (F,) float64
        Jaw opening per frame, in [0, 1].
    """

    time_codes: np.ndarray
    rate: float
    muscle_names: tuple
    contractions: np.ndarray
    jaw: np.ndarray

    @property
    def n_frames(self) -> int:
        return int(np.asarray(self.time_codes).size)
