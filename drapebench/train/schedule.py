"""Learning-rate schedule of the trainer: a step down at an epoch, then an optional linear decay to 0."""

from __future__ import annotations


def scheduled_lr(cfg, epoch: int, step_fraction: float, train_s: float) -> float:
    """Learning rate of a step under train config ``cfg`` (:class:`drapebench.schema.TrainConf`): ``lr``
    before epoch ``lr_switch_epoch`` (None: never), then ``lr_after``; with ``lr_decay_fraction`` f it
    decays linearly to 0 over the last f of the budget: of the steps (``step_fraction`` done), or of
    ``max_minutes`` when set (``train_s`` seconds trained so far, resumed runs included), whichever is further."""
    switched = cfg.lr_switch_epoch is not None and epoch >= cfg.lr_switch_epoch
    lr = cfg.lr_after if switched and cfg.lr_after is not None else cfg.lr
    if cfg.lr_decay_fraction:
        done = step_fraction if cfg.max_minutes is None else max(step_fraction, train_s / (60.0 * cfg.max_minutes))
        lr *= min(1.0, max(0.0, 1.0 - done) / cfg.lr_decay_fraction)
    return lr


def clock_driven(cfg, step_fraction: float, train_s: float) -> bool:
    """Whether the decay of :func:`scheduled_lr` at this step follows the clock rather than the steps: ``max_minutes``'
    share used (``train_s`` s) is ahead of the steps' share and inside the decay. A model trained so depends on the
    speed of the machine that trained it, even when it reaches its last step."""
    if not cfg.lr_decay_fraction or cfg.max_minutes is None:
        return False
    by_time = train_s / (60.0 * cfg.max_minutes)
    return by_time > step_fraction and 1.0 - by_time < cfg.lr_decay_fraction


STOPS = ("done", "clock", "time")  # how a training ended, from deterministic to cut (TrainResult.stopped)


def combined_stop(*stops: str) -> str:
    """How a training of several stages ended: the least deterministic of their ``stopped`` values (:data:`STOPS`)."""
    return max(stops, key=STOPS.index, default="done")
