"""Evaluating a fitted transfer over a sequence: one float32 GEMM per block of frames, in chunks.

Every frame, whatever its validity pattern, goes through the same N x M transfer matrix B once its
marker displacements are made effective (:class:`~usdface.rbf.patterns.PatternCache`):
:func:`generate_chunks` yields (f, N, 3) chunks of vertex displacements, each computed by
:func:`evaluate_frames` as ``(3 f', M) @ B^T`` into a reused GEMM temporary, optionally with an
offset added in the same product and each frame's bounding box. Memory stays bounded by one or two
chunks (~64 MiB each by default), the GEMM temporary (<= 32 MiB) and B.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, OptionError
from .parameters import as_float_array, shape_error
from .patterns import PatternCache
from .solver import FittedTransfer

__all__ = ["ChunkPlan", "check_chunk_frames", "plan_chunks", "offset_rhs", "evaluate_frames", "generate_chunks"]

_CHUNK_BYTES = 64 << 20  # default output chunk size of iter_chunks()
_GEMM_TEMP_BYTES = 32 << 20  # GEMM temporary (a block of frames) in iter_chunks()


def check_chunk_frames(value) -> int:
    """``value`` as frames per chunk: an integer >= 1, else an :class:`OptionError` naming it."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise OptionError(f"chunk_frames: expected an integer >= 1; got {value!r}")
    return int(value)


@dataclass(frozen=True)
class ChunkPlan:
    """How a sequence is evaluated (checked by :func:`plan_chunks` and the transfer's ``iter_chunks``).

    Attributes
    ----------
    chunk_frames : int
        Frames per chunk (>= 1).
    dtype : numpy.dtype
        float32 or float64 (the float64 transfer matrix: the accuracy path).
    blas_threads : int, optional
        Limit of numpy's BLAS threads during evaluation (threadpoolctl); None leaves them alone.
    n_buffers : int
        0: a fresh array per chunk; k >= 1: cycle through k output buffers.
    rhs : ndarray, shape (M + 3, N), optional
        ``[B^T; offset^T]`` from :func:`offset_rhs`: adds a per-vertex offset inside the GEMM.
    extents : bool
        Also yield each frame's bounding box.
    """

    chunk_frames: int
    dtype: np.dtype
    blas_threads: int | None = None
    n_buffers: int = 0
    rhs: np.ndarray | None = None
    extents: bool = False


def plan_chunks(n_vertices: int, chunk_frames, dtype, blas_threads) -> ChunkPlan:
    """The checked plan: ``dtype`` float32 or float64, ``chunk_frames`` (None: ~64 MiB of output),
    ``blas_threads`` an integer >= 1 or None; an :class:`OptionError` naming the bad one."""
    dtype = np.dtype(dtype)
    if dtype not in (np.float32, np.float64):
        raise OptionError(f"dtype: expected float32 or float64; got {dtype}")
    if chunk_frames is None:
        chunk_frames = max(1, _CHUNK_BYTES // (n_vertices * 3 * dtype.itemsize))
    else:
        chunk_frames = check_chunk_frames(chunk_frames)
    if blas_threads is not None and (
        isinstance(blas_threads, bool) or not isinstance(blas_threads, (int, np.integer)) or blas_threads < 1
    ):
        raise OptionError(f"blas_threads: expected an integer >= 1 or None; got {blas_threads!r}")
    return ChunkPlan(chunk_frames=chunk_frames, dtype=dtype, blas_threads=blas_threads)


def _transfer_matrix(fitted: FittedTransfer, dtype) -> np.ndarray:
    return fitted.B32 if np.dtype(dtype) == np.float32 else fitted.B64


def offset_rhs(fitted: FittedTransfer, offset, dtype) -> np.ndarray:
    """(M + 3, N) right factor ``[B^T; offset^T]`` of the GEMM that adds ``offset`` (N, 3, mesh units)."""
    N, M = fitted.B64.shape
    off = as_float_array("offset", offset)
    if off.shape != (N, 3):
        raise shape_error("offset", f"(N, 3) = ({N}, 3)", offset)
    if not np.isfinite(off).all():
        raise InputError(f"offset: {int((~np.isfinite(off)).any(axis=1).sum())} point(s) are NaN or infinite")
    rhs = np.empty((M + 3, N), dtype=dtype)
    rhs[:M] = _transfer_matrix(fitted, dtype).T
    rhs[M:] = off.T
    return rhs


def _gemm_buffer(n_vertices: int, frames: int, dtype) -> np.ndarray:
    """GEMM temporary for blocks of up to ``frames`` frames, reused across chunks."""
    sub = int(min(frames, max(1, _GEMM_TEMP_BYTES // (3 * n_vertices * np.dtype(dtype).itemsize))))
    return np.empty((3 * sub, n_vertices), dtype=dtype)


def evaluate_frames(fitted: FittedTransfer, eff: np.ndarray, out: np.ndarray, tmp: np.ndarray | None = None, *,
                    rhs: np.ndarray | None = None, extents: np.ndarray | None = None) -> None:
    """out[k] = B @ eff[k] for every frame k of a chunk (out: (f, N, 3), C-contiguous).

    One GEMM per block of frames, ``(3 f', M) @ B^T (M, N) -> (3 f', N)`` (rows ordered frame,
    component), then three strided copies interleave x, y, z into the (f', N, 3) output. This
    orientation keeps the GEMM efficient (B is streamed once per block of frames) and the
    interleaving copy cheap; a per-frame product would re-read B every frame.

    ``rhs`` (M + 3, N), from :func:`offset_rhs`, adds a per-vertex offset inside the same GEMM
    (the extra rows of the left factor are the unit vectors of x, y, z); ``extents`` (f, 2, 3)
    receives each frame's bounding box, reduced over the contiguous rows of the GEMM result
    (much cheaper than over the interleaved output).
    """
    f, M = eff.shape[:2]
    N = out.shape[1]
    if rhs is None:
        rhs = _transfer_matrix(fitted, out.dtype).T
        lhs = np.ascontiguousarray(eff.transpose(0, 2, 1).reshape(3 * f, M), dtype=out.dtype)
    else:
        lhs = np.zeros((f, 3, M + 3), dtype=out.dtype)
        lhs[:, :, :M] = eff.transpose(0, 2, 1)
        lhs[:, np.arange(3), M + np.arange(3)] = 1.0
        lhs = lhs.reshape(3 * f, M + 3)
    if tmp is None:
        tmp = _gemm_buffer(N, f, out.dtype)
    sub = tmp.shape[0] // 3
    for a in range(0, f, sub):
        b = min(f, a + sub)
        t = np.matmul(lhs[3 * a : 3 * b], rhs, out=tmp[: 3 * (b - a)]).reshape(b - a, 3, N)
        if extents is not None:
            t.min(axis=2, out=extents[a:b, 0])
            t.max(axis=2, out=extents[a:b, 1])
        dst = out[a:b]
        for c in range(3):
            dst[:, :, c] = t[:, c, :]


def generate_chunks(fitted: FittedTransfer, patterns: PatternCache, all_invalid: str, disp: np.ndarray,
                    scan: tuple, plan: ChunkPlan, out: np.ndarray | None = None) -> Iterator[tuple]:
    """Yield ``(frames, points)`` (and ``boxes`` with ``plan.extents``) chunk by chunk.

    Parameters
    ----------
    fitted : FittedTransfer
    patterns : PatternCache
        Holds every pattern of ``scan``.
    all_invalid : {"error", "hold", "zero"}
    disp : ndarray, shape (F, M, 3), float
        Marker displacements (mesh units).
    scan : (valid, pid, keys)
        :meth:`PatternCache.scan` of ``disp``.
    plan : ChunkPlan
    out : ndarray, shape (F, N, 3), optional
        Evaluate in place into its frame slices (then the chunks are views of it).
    """
    valid, pid, keys = scan
    F = disp.shape[0]
    if F == 0:
        return
    N = fitted.B64.shape[0]
    chunk_frames, dtype = plan.chunk_frames, plan.dtype
    tmp = _gemm_buffer(N, min(F, chunk_frames), dtype)
    ring = []
    if plan.n_buffers and out is None:
        ring = [np.empty((min(F, chunk_frames), N, 3), dtype=dtype)
                for _ in range(min(plan.n_buffers, -(-F // chunk_frames)))]
    limiter = None
    if plan.blas_threads is not None:
        from threadpoolctl import ThreadpoolController

        limiter = ThreadpoolController()
    held = None
    for i, a in enumerate(range(0, F, chunk_frames)):
        b = min(F, a + chunk_frames)
        eff = patterns.effective(disp[a:b], (valid[a:b], pid[a:b], keys), all_invalid, held)
        held = eff[-1].copy()
        if out is not None:
            chunk = out[a:b]
        elif ring:
            chunk = ring[i % len(ring)][: b - a]
        else:
            chunk = np.empty((b - a, N, 3), dtype=dtype)
        boxes = np.empty((b - a, 2, 3), dtype=dtype) if plan.extents else None
        if limiter is None:
            evaluate_frames(fitted, eff, chunk, tmp, rhs=plan.rhs, extents=boxes)
        else:
            with limiter.limit(limits=int(plan.blas_threads), user_api="blas"):
                evaluate_frames(fitted, eff, chunk, tmp, rhs=plan.rhs, extents=boxes)
        yield (slice(a, b), chunk, boxes) if plan.extents else (slice(a, b), chunk)
