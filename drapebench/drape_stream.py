"""A run's drape streamed to ``prediction.h5`` as the method makes it, so that a long drape of a method that drapes
frame by frame is never held whole: the run scores it from the file a chunk at a time."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import torch

from drapebench.errors import NonFiniteDrape
from drapebench.metrics import nonfinite_frames
from drapebench.results import StoredFrames, prediction_writer


@dataclass
class StreamedDrape:
    """What :func:`stream_drape` returns. ``on_device``: the method's :class:`methods.base.DrapeResult` on the run's
    device when it came whole (one chunk), else one whose ``vertices`` are the file's :class:`StoredFrames` (timings
    summed, no extras); ``result``: the same on the CPU, for the metrics, the export and the recording (``vertices[a:b]``
    is a tensor of those frames either way); ``drape_s``: the method's wall time (s), writing and checks left out."""

    on_device: object
    result: object
    drape_s: float


def stream_drape(method, garment, seq, path: str | Path, chunk_frames: int, method_name: str, attrs: dict) -> StreamedDrape:
    """Drape ``garment`` on ``seq`` with ``method`` (:meth:`methods.base.DrapingMethod.drape_chunks`, at most
    ``chunk_frames`` frames a chunk for a method that streams), each chunk checked for NaN/Inf and appended to the
    prediction file ``path`` (:func:`drapebench.results.prediction_writer`, with the faces and the attributes ``attrs``) as it comes.
    Raises :class:`drapebench.errors.NonFiniteDrape` naming every non-finite frame (``method_name``'s; the file is not
    written) and ValueError for ``chunk_frames`` < 1 or chunks that do not make the sequence."""
    from methods.base import DrapeResult

    if chunk_frames < 1:
        raise ValueError(f"chunk_frames must be >= 1 (frames draped, written and scored at once), got {chunk_frames}")
    held, timings, bad, n, drape_s = None, {}, [], 0, 0.0
    with prediction_writer(path, seq.n_frames, garment.faces, garment.n_vertices, **attrs) as writer:
        chunks = iter(method.drape_chunks(garment, seq, chunk_frames))
        while True:
            t = time.perf_counter()
            chunk = next(chunks, None)
            if chunk is not None and chunk.vertices.is_cuda:  # the drape's time is its kernels', not their launch
                torch.cuda.synchronize(chunk.vertices.device)
            drape_s += time.perf_counter() - t
            if chunk is None:
                break
            bad += [n + f for f in nonfinite_frames(chunk.vertices)]
            writer.append(chunk.vertices)
            held = chunk if n == 0 else None  # a second chunk: the drape streams, nothing is held
            n += len(chunk.vertices)
            for k, v in chunk.timings_ms.items():
                timings[k] = timings.get(k, 0.0) + v
        if bad:
            raise NonFiniteDrape(method_name, bad, seq.n_frames)
    if held is not None:
        return StreamedDrape(held, replace(held, vertices=held.vertices.cpu(), extras={k: v.cpu() for k, v in held.extras.items()}), drape_s)
    stored = DrapeResult(StoredFrames(path, writer.digest), timings)
    return StreamedDrape(stored, stored, drape_s)
