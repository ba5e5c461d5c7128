"""The one training loop of every learned method.

A method describes its training as an :class:`Objective` (parameter groups, a batch source, named and
already-weighted loss terms, and a key naming the run); :func:`train` runs Adam on it under a
:class:`drapebench.schema.TrainConf` budget: learning-rate schedule, optional gradient clipping and
weight averaging (EMA), a guard that stops on a non-finite loss term or gradient, resumable atomic
checkpoints, a time budget, a progress bar (a log line every ``log_every`` steps without one) and ``losses.csv``.

Best state: with a time budget, every checkpoint compares the mean training loss of the steps since
the previous checkpoint with the lowest such mean so far and keeps a copy of the weights (the averaged
ones with EMA) where it is lower; a run cut by the time budget ends with that best state. A run that
completes its steps ends with its final state.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import torch

from drapebench.cache import cache_dir
from drapebench.errors import TrainingDiverged
from drapebench.keys import check_known, check_type
from drapebench.progress import progress, progress_enabled
from drapebench.results import git_commit
from drapebench.schema import TrainConf
from drapebench.train.checkpoint import load_state, remove_state, save_state, write_losses
from drapebench.train.schedule import clock_driven, scheduled_lr

log = logging.getLogger("drapebench")


@dataclass
class Step:
    """Where the loop is: ``step`` (0-based, the step being computed), ``epoch``, and the run's numpy
    generator ``rng`` (seeded by the train config; checkpointed), for random draws of a batch."""

    step: int
    epoch: int
    rng: np.random.Generator


@dataclass
class Objective:
    """What a learned method gives the trainer.

    name: label of the progress bar, messages and checkpoint files.
    param_groups: ``[{"params": [tensors], "lr_factor": f}, ...]``; each group learns at f x the scheduled rate,
        with Adam's ``eps`` and ``weight_decay`` (an L2 penalty's gradient, per unit weight) if the group gives them
        (else torch's 1e-8 and 0); a group with a ``name`` has its gradient's
        norm before clipping logged per step as ``grad_norm_<name>``.
    n_items: training items (e.g. windows of frames) in one epoch; batches are shuffled indices into them.
    batch: (item indices (b,), Step) -> a batch, whatever ``loss_terms`` takes.
    loss_terms: (batch, Step) -> {term name: scalar tensor}, each term already weighted; the loss is their sum.
    key: content hash of everything that determines the run (method and training settings, seed, garment,
        body, material, data); resuming needs the same key.
    evaluate: optional () -> {name: float}, called after every completed epoch (e.g. a validation metric);
        its records (with the epoch and step) are :attr:`TrainResult.evaluations` and ``evaluations.csv``.
    """

    name: str
    param_groups: list[dict]
    n_items: int
    batch: Callable[[np.ndarray, Step], Any]
    loss_terms: Callable[[Any, Step], dict[str, torch.Tensor]]
    key: str
    evaluate: Callable[[], dict[str, float]] | None = None


@dataclass
class TrainResult:
    """train_s: training time in s (resumed runs included); n_steps: steps done; history: one record per
    step (step, epoch, lr, loss, each term, grad_norm); stopped: "done" (every step, on the steps' schedule),
    "clock" (every step, but the lr decay followed ``max_minutes``' clock ahead of the steps at some step: a machine
    slower than the budget assumes) or "time" (cut by ``max_minutes``); resumed_from: the
    checkpoint a resumed run started from; evaluations: one record per completed epoch (epoch, step and
    the values of :attr:`Objective.evaluate`), empty without it."""

    train_s: float
    n_steps: int
    history: list[dict] = field(default_factory=list)
    stopped: str = "done"
    resumed_from: str | None = None
    evaluations: list[dict] = field(default_factory=list)


# key: (whether a given value (not null) is in range, the range in words, an example of a value in range)
_RANGES: dict[str, tuple[Callable[[float], bool], str, str]] = {
    "seed": (lambda v: v >= 0, ">= 0 (it seeds numpy's generator)", "0"),
    "epochs": (lambda v: v >= 0, ">= 0 (0: no step, the untrained model)", "4"),
    "steps": (lambda v: v >= 0, ">= 0 (0: no step, the untrained model), or null to count epochs", "3300"),
    "batch_size": (lambda v: v >= 1, ">= 1", "8"),
    "lr": (lambda v: math.isfinite(v) and v > 0, "a finite rate > 0", "1e-4"),
    "lr_after": (lambda v: math.isfinite(v) and v >= 0, "a finite rate >= 0, or null to keep lr", "1e-4"),
    "lr_switch_epoch": (lambda v: v >= 0, ">= 0, or null to keep lr throughout", "8"),
    "lr_decay_fraction": (lambda v: 0 <= v <= 1, "a fraction of the budget in [0, 1], or null for no decay", "0.5"),
    "grad_clip": (lambda v: math.isfinite(v) and v > 0, "a finite norm > 0, or null for no clipping", "20"),
    "ema_decay": (lambda v: 0 <= v < 1, "in [0, 1) (0: no averaging), or null for no averaging", "0.995"),
    "max_minutes": (lambda v: math.isfinite(v) and v > 0, "a finite time > 0, or null for no time budget", "10"),
    "checkpoint_every": (lambda v: v >= 1, ">= 1 step", "100"),
    "log_every": (lambda v: v >= 1, ">= 1 step", "10"),
}


def train_config(cfg: Mapping[str, Any] | TrainConf | None) -> TrainConf:
    """A :class:`TrainConf` from a train config mapping (``conf/train``). Raises ValueError naming the key
    (``train.<key>``), the value and a fix for an unknown key (listing the valid ones), a value of the wrong type
    (a string for a number, NaN) and one out of its range (a negative rate, clip or budget, a batch of 0, an
    EMA decay of 1 or more: each would train silently the wrong way, or fail later with a bare error)."""
    if isinstance(cfg, TrainConf):
        return cfg
    cfg = dict(cfg or {})
    check_known(cfg, [f.name for f in dataclasses.fields(TrainConf)], "train parameter")
    hints = typing.get_type_hints(TrainConf)
    for key, value in cfg.items():
        check_type(value, hints[key], "train parameter", key, "train.")
        if key in _RANGES and value is not None and not _RANGES[key][0](value):
            _, rule, example = _RANGES[key]
            raise ValueError(f"train.{key} must be {rule}, got {value!r}; e.g. train.{key}={example}")
    return TrainConf(**cfg)


def _bad_terms(terms: dict[str, torch.Tensor]) -> list[str]:
    return [k for k, v in terms.items() if not torch.isfinite(v).all()]


def train(objective: Objective, cfg: Mapping[str, Any] | TrainConf | None, log_dir: str | Path | None = None,
          checkpoint_dir: str | Path | None = None) -> TrainResult:  # fmt: skip
    """Train ``objective`` under budget ``cfg`` (see the module docstring). Writes ``losses.csv`` (and
    ``evaluations.csv`` with :attr:`Objective.evaluate`) into ``log_dir`` when given, and a resumable checkpoint ``<name>_partial_<key>.pt`` into ``checkpoint_dir``
    (default: the cache's ``checkpoints``) every ``checkpoint_every`` steps, sealed with a SHA-256 sidecar like every
    cached file (one that fails it is not resumed from, and neither is any under ``force=true``; one written by another commit
    is resumed with a warning naming both), removed when training ends.
    Raises :class:`drapebench.errors.TrainingDiverged` naming the step and the loss term(s) on a
    non-finite loss, and the step on a non-finite gradient (no step is taken on either)."""
    cfg = train_config(cfg)
    ob = objective
    if ob.n_items < 1:
        raise ValueError(f"{ob.name}: no training items (empty training data)")
    steps_per_epoch = max(1, math.ceil(ob.n_items / cfg.batch_size))
    total = int(cfg.steps) if cfg.steps is not None else steps_per_epoch * int(cfg.epochs)
    opt = torch.optim.Adam([{"params": g["params"], "factor": g["lr_factor"], "eps": g.get("eps", 1e-8), "weight_decay": g.get("weight_decay", 0.0)}
                            for g in ob.param_groups], lr=cfg.lr)  # fmt: skip
    named = [(g["name"], g["params"]) for g in ob.param_groups if "name" in g]
    params = [p for g in opt.param_groups for p in g["params"]]
    device = params[0].device  # the run's device: the objective's tensors live there
    path = Path(checkpoint_dir or cache_dir("checkpoints")) / f"{ob.name}_partial_{ob.key}.pt"
    rng = np.random.default_rng(cfg.seed)
    step, history, evaluations, t_prev, best_loss, best, resumed, clocked = 0, [], [], 0.0, math.inf, None, None, False
    ema = [p.detach().clone() for p in params] if cfg.ema_decay else None
    state = load_state(path, ob.key)
    if state is None and path.exists():
        log.info("%s: not resuming from %s; training starts at step 0", ob.name, path)
    if state is None:
        order = rng.permutation(ob.n_items)  # one draw more than used: the seeds keep their shuffles of earlier versions
    else:  # the state is read onto the CPU: tensors go back to their parameters' device
        with torch.no_grad():
            for p, saved in zip(params, state["params"]):
                p.copy_(saved)
        opt.load_state_dict(state["opt"])  # moves its state to each parameter's device
        step, history, t_prev, rng, order = state["step"], state["history"], state["train_s"], state["rng"], state["order"]
        evaluations, clocked = state.get("evaluations", []), state.get("clocked", False)
        torch.set_rng_state(state["torch_rng"])
        if state.get("cuda_rng") is not None and device.type == "cuda":
            torch.cuda.set_rng_state(state["cuda_rng"], device)
        ema, best_loss, best = (_on(state["ema"], params), state["best_loss"], _on(state["best"], params))
        resumed = str(path)
        log.info("%s: resuming from step %d of %d (%s)", ob.name, step, total, path)
        if state.get("commit") != git_commit():  # the key holds the configuration, not the code
            log.warning("%s: the state at %s was written by commit %s, this process runs %s; if the training code changed "
                        "between them, rerun with force=true (or delete that file) to train from step 0",
                        ob.name, path, state.get("commit", "unknown"), git_commit())  # fmt: skip
    t0 = time.perf_counter()
    deadline = None if cfg.max_minutes is None else cfg.max_minutes * 60 - t_prev
    bar = progress(total=total, initial=step, desc=ob.name, unit="step")
    stopped, since_ckpt = "done", []
    while step < total:
        epoch, k = divmod(step, steps_per_epoch)
        if k == 0:
            order = rng.permutation(ob.n_items)
        at = Step(step, epoch, rng)
        trained_s = t_prev + time.perf_counter() - t0
        lr = scheduled_lr(cfg, epoch, step / total, trained_s)
        clocked = clocked or clock_driven(cfg, step / total, trained_s)
        for g in opt.param_groups:
            g["lr"] = g["factor"] * lr
        batch = ob.batch(order[k * cfg.batch_size : (k + 1) * cfg.batch_size], at)
        terms = ob.loss_terms(batch, at)
        loss = sum(terms.values())
        if not torch.isfinite(loss):
            bad = _bad_terms(terms) or ["the sum of the terms"]
            values = ", ".join(f"{n}={v.item():.4g}" for n, v in terms.items())
            raise TrainingDiverged(f"{ob.name}: non-finite loss term {', '.join(bad)} at step {step} (epoch {epoch}; {values}); "
                                   "lower train.lr or the loss weights, or try another seed")  # fmt: skip
        opt.zero_grad(set_to_none=True)
        loss.backward()
        group_norms = {f"grad_norm_{n}": _grad_norm(ps) for n, ps in named}
        grad_norm = torch.nn.utils.clip_grad_norm_(params, cfg.grad_clip or math.inf)  # the norm before clipping
        if not torch.isfinite(grad_norm):  # a finite loss can still have a non-finite gradient: never step on it
            raise TrainingDiverged(f"{ob.name}: non-finite gradient at step {step} (epoch {epoch}; loss {loss.item():.4g}); "
                                   "lower train.lr or set train.grad_clip, or try another seed")  # fmt: skip
        opt.step()
        step += 1
        if ema is not None:  # Polyak averaging with TF's warm-up: decay min(d, (1 + n) / (10 + n))
            with torch.no_grad():
                torch._foreach_lerp_(ema, [p.detach() for p in params], 1.0 - min(cfg.ema_decay, (1 + step) / (10 + step)))
        history.append({"step": step, "epoch": epoch, "lr": lr, "loss": loss.item(), **{n: v.item() for n, v in terms.items()},
                        "grad_norm": grad_norm.item(), **group_norms})  # fmt: skip
        since_ckpt.append(history[-1]["loss"])
        if step % cfg.log_every == 0:
            bar.set_postfix({n: f"{v:.3g}" for n, v in history[-1].items() if n not in ("step", "epoch")})
            if not progress_enabled():  # no bar (a log file, CI): the same figures as a log line
                log.info("%s step %d/%d: %s", ob.name, step, total, ", ".join(f"{n} {v:.4g}" for n, v in history[-1].items() if n not in ("step", "epoch")))
        bar.update(1)
        if ob.evaluate is not None and (step % steps_per_epoch == 0 or step == total):
            with torch.no_grad():
                evaluations.append({"epoch": epoch, "step": step, **ob.evaluate()})
        elapsed = time.perf_counter() - t0
        timed_out = deadline is not None and elapsed > deadline and step < total
        if step % cfg.checkpoint_every == 0 or step == total or timed_out:
            if cfg.max_minutes is not None and np.mean(since_ckpt) < best_loss:
                best_loss, best = float(np.mean(since_ckpt)), [t.detach().clone() for t in (ema or params)]
            since_ckpt = []
            save_state(path, {"key": ob.key, "commit": git_commit(), "step": step, "history": history, "train_s": t_prev + elapsed, "params": params,
                              "opt": opt.state_dict(), "rng": rng, "torch_rng": torch.get_rng_state(), "order": order,
                              "cuda_rng": torch.cuda.get_rng_state(device) if device.type == "cuda" else None,
                              "ema": ema, "best_loss": best_loss, "best": best, "evaluations": evaluations, "clocked": clocked})  # fmt: skip
            if log_dir is not None:
                write_logs(log_dir, history, evaluations)
        if timed_out:
            log.warning("%s: max_minutes (%g) reached at step %d of %d; keeping the state of lowest mean training loss "
                        "(%.4g); a time-cut run depends on machine speed (raise max_minutes or lower the steps for a "
                        "deterministic result)", ob.name, cfg.max_minutes, step, total, best_loss)  # fmt: skip
            stopped = "time"
            break
    bar.close()
    if stopped == "done" and clocked:
        stopped = "clock"
        log.warning("%s: the learning rate decayed by max_minutes' clock (%g) ahead of the steps: every step ran, but the model "
                    "depends on machine speed (train on an idle machine, or raise max_minutes, for a deterministic result)",
                    ob.name, cfg.max_minutes)  # fmt: skip
    with torch.no_grad():
        final = best if stopped == "time" and best is not None else ema
        if final is not None:  # the averaged (or best) weights are the model
            torch._foreach_copy_(params, final)
    if log_dir is not None:
        write_logs(log_dir, history, evaluations)
    remove_state(path)
    return TrainResult(t_prev + time.perf_counter() - t0, step, history, stopped, resumed, evaluations)


def _on(saved: list[torch.Tensor] | None, params: list[torch.Tensor]) -> list[torch.Tensor] | None:
    """Saved copies of ``params`` (read onto the CPU) on their parameters' devices; None stays None."""
    return None if saved is None else [t.to(p.device) for t, p in zip(saved, params)]


def _grad_norm(params: list[torch.Tensor]) -> float:
    """The global 2-norm of the gradients of ``params`` (0 where none has one)."""
    grads = [p.grad for p in params if p.grad is not None]
    return torch.linalg.vector_norm(torch.stack([torch.linalg.vector_norm(g) for g in grads])).item() if grads else 0.0


def write_logs(log_dir: str | Path, history: list[dict], evaluations: list[dict]) -> None:
    """``losses.csv`` (one row per step) and, with evaluations, ``evaluations.csv`` (one row per epoch) into ``log_dir``;
    a log without rows (a run of 0 steps) is not written: a file of no columns is no table."""
    log_dir = Path(log_dir)
    log_dir.mkdir(parents=True, exist_ok=True)
    if history:
        write_losses(log_dir / "losses.csv", history)
    if evaluations:
        write_losses(log_dir / "evaluations.csv", evaluations)
