"""A toy learned method for the trainer's tests: two parameter tensors, two named loss terms, random
draws from both the run's numpy generator and torch's, and hooks to inject a NaN, an interruption or
a slow step. ``python -m tests.train.toy CKPT_DIR LOG_DIR OUT_JSON`` trains it (the kill -9 test)."""

from __future__ import annotations

import json
import sys
import time

import torch

from drapebench.train import Objective, train

BUDGET = {"steps": 40, "batch_size": 4, "lr": 0.05, "lr_after": 0.01, "lr_switch_epoch": 2, "grad_clip": 1.0,
          "ema_decay": 0.9, "checkpoint_every": 3, "log_every": 1}  # fmt: skip


def toy(nan_at=None, interrupt_at=None, sleep_s=0.0, slow_from=0, jump_at=None, key="toy", device="cpu"):
    """(Objective, [w (3,), v (2,)]). nan_at (term, step): that term is NaN at that step; interrupt_at:
    KeyboardInterrupt at that step; sleep_s: seconds per step from step slow_from on; jump_at: from that
    step on the 'fit' term is weighted 100x (the training loss rises); device: where the parameters and draws live."""
    torch.manual_seed(0)
    w = torch.nn.Parameter(torch.zeros(3, device=device))
    v = torch.nn.Parameter(torch.zeros(2, device=device))
    targets = torch.linspace(0.5, 1.5, 30, device=device).reshape(10, 3)

    def batch(items, at):
        return targets[items], float(at.rng.normal())

    def loss_terms(b, at):
        if at.step == interrupt_at:
            raise KeyboardInterrupt
        if at.step >= slow_from:
            time.sleep(sleep_s)
        t, noise = b
        jitter = 1e-2 * torch.randn(3, device=device)
        weight = 100.0 if jump_at is not None and at.step >= jump_at else 1.0
        terms = {"fit": weight * (w - t.mean(0) + jitter).square().sum(), "reg": 0.5 * (v - noise).square().sum()}
        if nan_at is not None and at.step == nan_at[1]:
            terms[nan_at[0]] = terms[nan_at[0]] * float("nan")
        return terms

    groups = [{"params": [w], "lr_factor": 1.0}, {"params": [v], "lr_factor": 0.5}]
    return Objective("toy", groups, 10, batch, loss_terms, key), [w, v]


if __name__ == "__main__":
    torch.set_num_threads(1)
    objective, params = toy(sleep_s=0.05)
    res = train(objective, BUDGET, log_dir=sys.argv[2], checkpoint_dir=sys.argv[1])
    with open(sys.argv[3], "w") as f:
        json.dump({"params": [p.tolist() for p in params], "history": res.history, "resumed_from": res.resumed_from}, f)
