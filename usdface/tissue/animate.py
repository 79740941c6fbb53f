"""Driving a Simulator through a timeline, frame by frame."""
from __future__ import annotations

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
