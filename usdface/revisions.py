"""Algorithm revisions: which version of its algorithms and defaults made a layer or a cached value.

A revision is an integer per processor (the name its layers' provenance gives, ``"transfer"``,
``"solve --corrective"``...), bumped whenever that processor's output changes for the same inputs
and options: a new algorithm or a changed default. Revision 1 is usdface 0.2's; a processor not in
:data:`REVISIONS` is still at 1. Per processor, not one number for the package, so that a change
to the transfer does not throw away the distance matrices the cache holds (the expensive part of a
shot), while any change a shot depends on makes it stale.

Where the revision is used:

- every layer's provenance (:func:`usdface.usd.layers.provenance`) records ``revision`` when it
  is above 1 (a layer without it was made at revision 1, so the layers of processors that never
  changed stay byte-identical to usdface 0.2's);
- `run`'s provenance (summary.json and the shot record) records ``revisions``, the revisions
  above 1 of every processor a run can call (:data:`RUN_PROCESSORS`): `batch --resume` compares it
  with the current one and redoes a shot made at an older revision instead of skipping it;
- the content cache (:func:`usdface.cache.content_key`) puts the revision of the processor that
  makes each kind of entry (:data:`CACHE_KINDS`) into the key: an entry made at an older revision
  is never read.

History (bump the number, add the line):

- 2: import-capture, bind, transfer, skel, solve, solve --corrective, fit-muscles (issue 19: the rest
  pose is averaged over the still stretch around the neutral frame, not taken from one frame;
  transfer: kernels sound or refused, the polynomial by default, the per-marker width rule, fast
  marching geodesics by default; solve: pose refit).
"""
from __future__ import annotations

import json

__all__ = ["REVISIONS", "RUN_PROCESSORS", "CACHE_KINDS", "revision", "provenance_revision", "run_revisions"]

#: processor (as its provenance names it) -> revision, for those above 1
REVISIONS: dict[str, int] = {
    "import-capture": 2,
    "bind": 2,
    "transfer": 2,
    "skel": 2,
    "solve": 2,
    "solve --corrective": 2,
    "fit-muscles": 2,
}

#: the processors whose layers a `run` writes (or computes through): its provenance carries their revisions
RUN_PROCESSORS = ("import-mesh", "track", "lift", "import-capture", "bind", "distances", "transfer", "skel", "solve")

#: content-cache kind -> the processor that makes its entries
CACHE_KINDS = {"capture": "import-capture", "distances": "distances"}


def revision(processor: str) -> int:
    """The current revision of ``processor`` (1 when it never changed)."""
    return REVISIONS.get(processor, 1)


def run_revisions() -> dict:
    """{processor: revision} of the processors a run calls whose revision is above 1."""
    return {p: REVISIONS[p] for p in RUN_PROCESSORS if p in REVISIONS}


def provenance_revision(processor: str) -> dict:
    """What a layer's provenance records of the revision: ``{"revision": N}`` above 1, nothing at 1;
    for ``"run"``, ``{"revisions": '{"bind": 2, ...}'}`` (JSON, as the options are) when any step is
    above 1."""
    if processor == "run":
        steps = run_revisions()
        return {"revisions": json.dumps(steps, sort_keys=True)} if steps else {}
    n = revision(processor)
    return {"revision": n} if n > 1 else {}
