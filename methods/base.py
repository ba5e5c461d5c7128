"""The interface every draping method implements, and the records it returns."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, Iterable, Iterator, Mapping, Sequence

import torch


@dataclass
class DrapeResult:
    """Output of :meth:`DrapingMethod.drape`.

    vertices: (T, V, 3) draped garment vertices in metres, one row per sequence frame.
    timings_ms: per-stage wall time in milliseconds for the whole sequence (e.g. {"network": .., "skinning": ..}).
    extras: intermediate stages a recording shows beside the drape: (T, V, 3) positions in metres (e.g.
        GenSim's "arap") or (T, V) bool vertex masks (e.g. its "handles").
    """

    vertices: torch.Tensor
    timings_ms: dict[str, float] = field(default_factory=dict)
    extras: dict[str, torch.Tensor] = field(default_factory=dict)

    @classmethod
    def joined(cls, chunks: Iterable[DrapeResult], n_frames: int) -> DrapeResult:
        """One result of consecutive chunks of frames (:meth:`DrapingMethod.drape_chunks`) that make ``n_frames``
        frames: their vertices filled into one (n_frames, V, 3) tensor as they come (no second copy), their timings
        summed; extras of a single chunk kept (chunks of several carry none)."""
        vertices, timings, extras, n = None, {}, {}, 0
        for chunk in chunks:
            if vertices is None:
                vertices, extras = chunk.vertices.new_empty((n_frames, *chunk.vertices.shape[1:])), chunk.extras
            else:
                extras = {}
            vertices[n : n + len(chunk.vertices)] = chunk.vertices
            n += len(chunk.vertices)
            for k, v in chunk.timings_ms.items():
                timings[k] = timings.get(k, 0.0) + v
        if n != n_frames:
            raise ValueError(f"the chunks hold {n} frames, not {n_frames}")
        return cls(vertices, timings, extras)


@dataclass
class FitReport:
    """Summary of :meth:`DrapingMethod.fit`: wall time (s), optimisation steps, last loss terms,
    per-step loss history, per-epoch evaluation records (methods whose objective evaluates, e.g. the VAE's
    collisions per epoch), the checkpoint a resumed training started from and how it stopped."""

    train_s: float = 0.0
    n_steps: int = 0
    final_losses: dict[str, float] = field(default_factory=dict)
    history: list[dict[str, float]] = field(default_factory=list)
    evaluations: list[dict[str, float]] = field(default_factory=list)
    resumed_from: str | None = None
    stopped: str = "done"  # "time": cut by train.max_minutes; "clock": every step, its lr decayed by that clock (drapebench.train.TrainResult)


class DrapingMethod(ABC):
    """A garment-draping method behind one interface.

    Lifecycle: ``m = methods.get(name)(cfg)``; ``m.fit(data, train_cfg)`` (trains, or only binds the
    body/material for methods with nothing to learn); ``m.drape(garment, seq)`` for inference.
    ``state_dict`` / ``load_state_dict`` hold everything needed to drape again without ``fit``
    (the pipeline binds the body/material first with :meth:`bind`).
    """

    name: str = "base"
    generic: bool = False  # one model for any garment (True) vs one model per garment
    needs_reference: bool = False  # trains on physics-based reference drapes
    learns: bool = False  # fit trains a model (with train.epochs > 0); False: fit only binds the body and material
    displaced_from: tuple[str, ...] = ()  # extras stages in the drape's space: the recording colours the drape by its distance from each

    def __init__(self, cfg: Mapping[str, Any] | None = None) -> None:
        self.cfg = dict(cfg or {})
        self.body = None
        self.material = None

    def bind(self, body, material) -> None:
        """Attach the body model and material the method drapes on (called by ``fit`` and the pipeline)."""
        self.body = body
        self.material = material

    def _require_bound(self) -> None:
        if self.body is None or self.material is None:
            raise RuntimeError(f"{self.name}: call fit(data, ...) or bind(body, material) before drape()")

    @abstractmethod
    def fit(self, data, train_cfg: Mapping[str, Any] | None = None) -> FitReport:
        """Train on ``data`` (a :class:`drapebench.data.TrainData`); returns a :class:`FitReport`."""

    @abstractmethod
    def drape(self, garment, seq) -> DrapeResult:
        """Drape ``garment`` over body sequence ``seq``; inference only, returns (T, V, 3) vertices."""

    def drape_chunks(self, garment, seq, chunk_frames: int) -> Iterator[DrapeResult]:
        """The drape of :meth:`drape` as consecutive chunks of frames, each a :class:`DrapeResult` of those frames
        with its share of the timings; what a run calls, writing each chunk to ``prediction.h5`` as it comes. A method
        that drapes frame by frame yields chunks of at most ``chunk_frames`` frames as it makes them, so a long drape
        is never held whole (lbs); the default yields :meth:`drape` whole, one chunk, for methods that need the whole
        sequence."""
        yield self.drape(garment, seq)

    def scored_variants(self, seq, result: DrapeResult) -> dict[str, torch.Tensor]:
        """Other drapes (T, V, 3) m of the same frames that a run scores beside ``result.vertices`` with the same
        metrics (metrics.json: ``<metric>@<name>``), computed outside the drape's timing; none by default. For a drape
        that came in several chunks (:meth:`drape_chunks`), ``result.vertices`` is its file's
        :class:`drapebench.results.StoredFrames` (``vertices[a:b]`` a tensor), here and in :meth:`diagnostics`."""
        return {}

    def diagnostics(self, garment, seq, result: DrapeResult) -> dict[str, float]:
        """Method-specific measurements of a drape ``result`` of ``garment`` on ``seq`` ({name: float}), computed
        after the timed drape and written to ``metrics.json``; none by default. Each name's label, unit and better
        direction are declared in the method package's ``metrics.py`` (``METRICS``, :mod:`drapebench.plugins`),
        which the tables read."""
        return {}

    def settings_key(self) -> Any:
        """Settings a trained state depends on beyond ``cfg`` (code defaults resolved), part of the checkpoint
        key so that changing a default retrains; None (the default) when ``cfg`` says it all. A dict of parameters
        that leaves out some keys of ``cfg`` (inference-only settings) leaves them out of the checkpoint key as well
        (:func:`drapebench.experiment.checkpoint_path`)."""
        return None

    def trained_beta_bound(self) -> Sequence[float] | None:
        """Per shape component k, the largest |beta_k| of the body shapes the model trains on when it draws them
        itself (e.g. U(-r_k, r_k)); None (the default): the shapes of its training dataset
        (:func:`drapebench.body.dataset.beta_bound`). A run warns when its test shape leaves this range."""
        return None

    def trained_body(self, run_body):
        """The body model a trained state is fitted to, part of the checkpoint key: the run's body (the
        default); a method that trains on a body of its own returns that one, so one checkpoint serves runs on
        any body."""
        return run_body

    def state_dict(self) -> dict[str, Any]:
        """Learned state (tensors and plain values); empty for methods with nothing to learn."""
        return {}

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore what :meth:`state_dict` returned."""
        if state:
            raise ValueError(f"{self.name} has no learned state, got keys {sorted(state)}")
