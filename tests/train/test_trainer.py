"""The trainer on a toy objective: the NaN/Inf guard, resume after an interruption (in process and a
real kill -9), the time budget and its best state, losses.csv, the learning-rate schedule."""

import csv
import json
import logging
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest
import torch

from drapebench.errors import TrainingDiverged
from drapebench.schema import TrainConf
from drapebench.train import scheduled_lr, train, train_config
from tests.devices import device_params
from tests.train.toy import BUDGET, toy

ROOT = Path(__file__).resolve().parents[2]


def _run(tmp_path, budget=BUDGET, **kw):
    objective, params = toy(**kw)
    return train(objective, budget, log_dir=tmp_path, checkpoint_dir=tmp_path / "ckpt"), params


def test_a_nan_in_one_term_stops_training_naming_the_term_and_the_step(tmp_path):
    objective, params = toy(nan_at=("reg", 5))
    seen = []
    inner = objective.loss_terms
    objective.loss_terms = lambda b, at: seen.append([p.detach().clone() for p in params]) or inner(b, at)
    with pytest.raises(TrainingDiverged, match=r"non-finite loss term reg at step 5 \(epoch 1; fit=.*reg=nan"):
        train(objective, BUDGET, checkpoint_dir=tmp_path)
    assert all(torch.equal(a, b) for a, b in zip(seen[-1], params))  # no step was taken on it


def test_named_groups_log_their_gradient_norms_before_clipping(tmp_path):
    objective, (w, v) = toy()
    objective.param_groups[0]["name"], objective.param_groups[1]["name"] = "w", "v"
    res = train(objective, BUDGET, checkpoint_dir=tmp_path)
    for h in res.history:
        assert h["grad_norm_w"] > 0 and h["grad_norm_v"] > 0
        assert h["grad_norm"] == pytest.approx((h["grad_norm_w"] ** 2 + h["grad_norm_v"] ** 2) ** 0.5, rel=1e-5)
    assert max(h["grad_norm"] for h in res.history) > BUDGET["grad_clip"]  # the logged norms are those before the clip


def test_a_non_finite_gradient_stops_before_the_step(tmp_path):
    objective, (w, v) = toy()
    objective.loss_terms = lambda b, at: {"root": w.abs().sqrt().sum()}  # finite (0) at w = 0, infinite slope
    with pytest.raises(TrainingDiverged, match="non-finite gradient at step 0"):
        train(objective, BUDGET, checkpoint_dir=tmp_path)
    assert torch.count_nonzero(w) == 0


def test_losses_csv_has_a_row_per_step_with_each_term(tmp_path):
    res, _ = _run(tmp_path)
    rows = list(csv.DictReader((tmp_path / "losses.csv").open()))
    assert len(rows) == res.n_steps == BUDGET["steps"] and res.stopped == "done"
    assert list(rows[0]) == ["step", "epoch", "lr", "loss", "fit", "reg", "grad_norm"]
    assert [int(r["step"]) for r in rows] == list(range(1, BUDGET["steps"] + 1))
    for r, h in zip(rows, res.history):
        assert float(r["loss"]) == pytest.approx(float(r["fit"]) + float(r["reg"]), rel=1e-6)
        assert float(r["grad_norm"]) == h["grad_norm"] and int(r["epoch"]) == h["epoch"]
    assert {float(r["lr"]) for r in rows} == {0.05, 0.01}  # the switch at epoch 2 (3 steps of 4 items an epoch)
    assert not list((tmp_path / "ckpt").glob("*.pt"))  # the resumable state is removed when training ends


def test_a_training_of_no_steps_writes_no_loss_log(tmp_path):
    """An untrained row (``train.epochs=0``) once left a losses.csv of no columns, which MLflow's tracker could not
    read, so the run went untracked."""
    res, _ = _run(tmp_path, budget={**BUDGET, "steps": 0})
    assert res.n_steps == 0 and not (tmp_path / "losses.csv").exists()


@device_params
def test_an_interrupted_run_resumes_from_its_checkpoint_and_ends_where_an_uninterrupted_run_ends(tmp_path, device):
    whole, params = _run(tmp_path / "a", device=device)
    with pytest.raises(KeyboardInterrupt):
        _run(tmp_path / "b", interrupt_at=7, device=device)
    assert [r["step"] for r in csv.DictReader((tmp_path / "b" / "losses.csv").open())] == ["1", "2", "3", "4", "5", "6"]
    resumed, params_b = _run(tmp_path / "b", device=device)  # the state is read onto the CPU, the run goes on on the device
    assert resumed.resumed_from is not None and resumed.history == whole.history  # RNG draws and optimizer state resumed
    assert all(p.device.type == device and torch.equal(a, b) for a, b, p in zip(params, params_b, params_b))
    other, _ = _run(tmp_path / "b", key="another run")  # a run with another key starts afresh
    assert other.resumed_from is None


def _flip_a_weight_byte(ckpt: Path) -> None:
    """Flip one byte inside a stored tensor's data (a bit error torch.load itself does not notice)."""
    with zipfile.ZipFile(ckpt) as z:
        info = next(i for i in z.infolist() if "/data/" in i.filename and i.file_size >= 8)
    data = bytearray(ckpt.read_bytes())
    local_extra = int.from_bytes(data[info.header_offset + 28 : info.header_offset + 30], "little")
    start = info.header_offset + 30 + len(info.filename.encode()) + local_extra  # local header: 30 bytes + name + extra
    data[start + 2] ^= 0x10
    ckpt.write_bytes(bytes(data))


@pytest.mark.parametrize("damage", ["truncated", "flipped"])
def test_a_damaged_partial_checkpoint_is_detected_by_its_checksum_and_not_resumed(tmp_path, caplog, damage):
    with pytest.raises(KeyboardInterrupt):
        _run(tmp_path, interrupt_at=4)
    (ckpt,) = (tmp_path / "ckpt").glob("toy_partial_*.pt")
    assert ckpt.with_name(ckpt.name + ".sha256").exists()  # sealed like every cached file
    if damage == "truncated":
        ckpt.write_bytes(ckpt.read_bytes()[:100])
    else:
        _flip_a_weight_byte(ckpt)
    with caplog.at_level(logging.WARNING, logger="drapebench"):
        res, params = _run(tmp_path)
    assert f"{ckpt} fails its checksum" in caplog.text
    assert res.resumed_from is None and res.n_steps == BUDGET["steps"]
    whole, params_whole = _run(tmp_path / "whole")
    assert res.history == whole.history and all(torch.equal(a, b) for a, b in zip(params, params_whole))  # started over
    assert not list((tmp_path / "ckpt").iterdir())  # state and seal removed at the end


def test_resuming_a_state_written_by_another_commit_warns_naming_both(tmp_path, caplog, monkeypatch):
    import drapebench.train.trainer as trainer

    for run in ("same", "other"):
        with pytest.raises(KeyboardInterrupt):
            _run(tmp_path / run, interrupt_at=4)
    with caplog.at_level(logging.WARNING, logger="drapebench"):
        same, _ = _run(tmp_path / "same")
    assert same.resumed_from is not None and "written by commit" not in caplog.text  # the same code: resumed quietly
    monkeypatch.setattr(trainer, "git_commit", lambda: "f00d" * 10)
    with caplog.at_level(logging.WARNING, logger="drapebench"):
        res, _ = _run(tmp_path / "other")
    assert res.resumed_from is not None  # resumed all the same: only the user knows whether the code changed
    assert "written by commit" in caplog.text and "this process runs " + "f00d" * 10 in caplog.text and "force=true" in caplog.text


def test_force_does_not_resume_from_a_partial_checkpoint(tmp_path):
    from drapebench.cache import forcing

    with pytest.raises(KeyboardInterrupt):
        _run(tmp_path, interrupt_at=4)
    with forcing():
        res, _ = _run(tmp_path)
    assert res.resumed_from is None and res.n_steps == BUDGET["steps"]


def test_kill_9_mid_training_then_the_same_command_continues(tmp_path):
    ckpt, out = tmp_path / "ckpt", tmp_path / "out.json"
    cmd = [sys.executable, "-m", "tests.train.toy", str(ckpt), str(tmp_path), str(out)]
    env = dict(os.environ, DRAPEBENCH_PROGRESS="0")
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env)
    t0 = time.time()
    while not list(ckpt.glob("*.pt")) and time.time() - t0 < 60:  # the first checkpoint (step 3 of 40, 50 ms a step)
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    assert proc.wait() == -signal.SIGKILL and not out.exists()
    subprocess.run(cmd, cwd=ROOT, env=env, check=True, timeout=120)
    got = json.loads(out.read_text())
    whole, params = _run(tmp_path / "whole", sleep_s=0.0)
    assert got["resumed_from"] is not None and got["history"] == whole.history
    assert got["params"] == [p.tolist() for p in params]


def test_the_time_budget_stops_with_a_warning_and_keeps_the_state_of_lowest_training_loss(tmp_path, caplog):
    budget = {**BUDGET, "steps": 50, "checkpoint_every": 1, "ema_decay": None, "max_minutes": 1.0 / 60}
    objective, (w, v) = toy(sleep_s=0.4, slow_from=2, jump_at=2)  # the loss jumps 100x from step 2: earlier is best
    at_step = []
    inner = objective.loss_terms
    objective.loss_terms = lambda b, at: at_step.append(w.detach().clone()) or inner(b, at)
    with caplog.at_level(logging.WARNING, logger="drapebench"):
        res = train(objective, budget, log_dir=tmp_path, checkpoint_dir=tmp_path)
    assert res.stopped == "time" and 3 <= res.n_steps < 50 and "max_minutes" in caplog.text
    losses = [h["loss"] for h in res.history]
    best = losses.index(min(losses))
    assert best < 2 and torch.equal(w, at_step[best + 1])  # before the jump; the weights after that step
    assert not torch.equal(w, at_step[-1])


def test_a_training_whose_lr_decay_followed_the_clock_says_so_though_it_ran_every_step(tmp_path, caplog):
    """A slow first step (1.2 s of a 2 s max_minutes) puts the clock's share ahead of the steps' inside the decay: every
    step runs, the training ends "clock" (its model depends on machine speed) and warns; with ample time it is "done"."""

    def slow_start(objective):
        inner = objective.loss_terms
        objective.loss_terms = lambda b, at: (time.sleep(1.2) if at.step == 0 else None) or inner(b, at)
        return objective

    budget = {**BUDGET, "steps": 20, "ema_decay": None, "lr_switch_epoch": None, "lr_decay_fraction": 0.5}
    with caplog.at_level(logging.WARNING, logger="drapebench"):
        res = train(slow_start(toy(key="clock")[0]), {**budget, "max_minutes": 2.0 / 60}, checkpoint_dir=tmp_path)
    assert res.stopped == "clock" and res.n_steps == 20 and "clock" in caplog.text
    assert res.history[1]["lr"] < BUDGET["lr"] - 1e-12  # decayed at step 1 of 20, by the clock
    ample = train(slow_start(toy(key="ample")[0]), {**budget, "max_minutes": 1.0}, checkpoint_dir=tmp_path)
    assert ample.stopped == "done" and ample.history[1]["lr"] == pytest.approx(BUDGET["lr"])


def test_lr_decays_over_the_step_or_the_time_budget_whichever_is_further():
    tp = TrainConf(lr=1e-3, lr_after=1e-4, lr_switch_epoch=2, lr_decay_fraction=0.5, max_minutes=None)
    assert scheduled_lr(tp, 0, 0.25, 1e6) == pytest.approx(1e-3)  # no time budget: the time is ignored
    assert scheduled_lr(tp, 0, 0.75, 0.0) == pytest.approx(0.5e-3) and scheduled_lr(tp, 0, 1.0, 0.0) == 0.0
    assert scheduled_lr(tp, 2, 0.5, 0.0) == pytest.approx(1e-4)  # after the switch epoch
    timed = TrainConf(lr=1e-3, lr_after=1e-4, lr_switch_epoch=2, lr_decay_fraction=0.5, max_minutes=10.0)
    assert scheduled_lr(timed, 0, 0.25, 450.0) == pytest.approx(0.5e-3)  # 75 % of 10 min: halfway down
    assert scheduled_lr(timed, 0, 0.25, 700.0) == 0.0  # past the time budget: never negative
    assert scheduled_lr(TrainConf(lr=1e-3, lr_switch_epoch=None), 50, 0.9, 0.0) == pytest.approx(1e-3)


def test_an_unknown_train_key_is_named():
    with pytest.raises(ValueError, match=r"unknown train parameter\(s\) \['window'\]; valid: \[.*'epochs'"):
        train_config({"epochs": 2, "window": 3})


@pytest.mark.parametrize("key, value", [("lr", -0.01), ("lr", float("inf")), ("lr_after", -0.01), ("grad_clip", -1.0), ("grad_clip", 0.0),
                                        ("ema_decay", 1.5), ("ema_decay", 1.0), ("lr_decay_fraction", -1.0), ("max_minutes", -1.0),
                                        ("steps", -1), ("epochs", -1), ("batch_size", 0), ("checkpoint_every", 0), ("log_every", 0),
                                        ("lr_switch_epoch", -2)])  # fmt: skip
def test_a_train_value_out_of_its_range_is_named_with_a_fix(key, value):
    """Each of these once trained silently the wrong way (a negative rate or clip ascends the loss, a decay >= 1
    freezes the averaged weights), only warned (a negative time budget) or failed later with a bare error (a batch
    of 0: ZeroDivisionError; a checkpoint interval of 0: modulo by zero)."""
    with pytest.raises(ValueError, match=rf"train\.{key} must be .*, got {value!r}; e\.g\. train\.{key}="):
        train_config({key: value})


@pytest.mark.parametrize("key, value", [("lr", float("nan")), ("lr", "1e-3x"), ("batch_size", 8.5), ("ema_decay", float("nan"))])
def test_a_train_value_of_the_wrong_type_is_named(key, value):
    with pytest.raises(ValueError, match=rf"train parameter {key} must be an? \w+( or None)?, not .*\(train\.{key}=\.\.\.\)"):
        train_config({key: value})


def test_the_edges_of_the_train_ranges_are_accepted():
    """0 steps or epochs is the untrained model (a row of the tables), 0 EMA decay no averaging, null the key's default."""
    for given in ({"epochs": 0}, {"steps": 0}, {"ema_decay": 0.0}, {"lr_after": None, "grad_clip": None, "max_minutes": None},
                  {"lr_decay_fraction": 1.0, "lr_switch_epoch": 0, "batch_size": 1, "checkpoint_every": 1, "log_every": 1}):  # fmt: skip
        assert train_config(given) == TrainConf(**given)


def test_an_epoch_evaluation_runs_after_every_epoch_and_survives_a_resume(tmp_path):
    def with_eval(**kw):
        objective, params = toy(**kw)
        objective.evaluate = lambda: {"w_norm": float(params[0].norm())}
        return objective, params

    objective, params = with_eval()
    whole = train(objective, BUDGET, log_dir=tmp_path / "a", checkpoint_dir=tmp_path / "a" / "ckpt")
    assert [e["epoch"] for e in whole.evaluations] == list(range(14))  # 40 steps of 3 per epoch: 13 epochs and a last part
    assert whole.evaluations[-1]["step"] == 40
    assert whole.evaluations[0]["w_norm"] < whole.evaluations[-2]["w_norm"]  # w moves from 0 towards its targets
    rows = list(csv.DictReader((tmp_path / "a" / "evaluations.csv").open()))
    assert [int(r["step"]) for r in rows] == [e["step"] for e in whole.evaluations]
    objective, _ = with_eval(interrupt_at=7)
    with pytest.raises(KeyboardInterrupt):
        train(objective, BUDGET, log_dir=tmp_path / "b", checkpoint_dir=tmp_path / "b" / "ckpt")
    objective, _ = with_eval()
    resumed = train(objective, BUDGET, log_dir=tmp_path / "b", checkpoint_dir=tmp_path / "b" / "ckpt")
    assert resumed.resumed_from is not None
    assert [e["step"] for e in resumed.evaluations] == [e["step"] for e in whole.evaluations]


def test_a_group_s_adam_eps_makes_its_steps_proportional_to_the_gradient(tmp_path):
    """With eps far above the gradient, Adam's step is about lr x g / eps (a small gradient moves its weight
    little); with torch's eps every weight moves by about lr, whatever its gradient."""
    budget = {**BUDGET, "steps": 1, "ema_decay": 0.0, "grad_clip": None}
    moved = {}
    for eps in (None, 1e3):
        objective, (w, v) = toy()
        if eps is not None:
            objective.param_groups[1]["eps"] = eps
        train(objective, budget, checkpoint_dir=tmp_path / str(eps))
        moved[eps] = v.detach().abs().max().item()
    lr_v = BUDGET["lr"] * 0.5
    assert moved[None] == pytest.approx(lr_v, rel=1e-3)  # Adam's first step: lr per weight
    assert moved[1e3] < 1e-2 * lr_v


def test_a_training_of_several_stages_ends_as_its_least_deterministic_stage():
    from drapebench.train import combined_stop

    assert combined_stop("done", "clock", "done") == "clock" and combined_stop("clock", "time") == "time"
    assert combined_stop("done") == "done" and combined_stop() == "done"


def test_grad_clip_scales_the_gradient_the_step_takes_to_the_clip(tmp_path):
    objective, params = toy()
    res = train(objective, {**BUDGET, "steps": 1, "ema_decay": None}, checkpoint_dir=tmp_path)
    assert res.history[0]["grad_norm"] > 2 * BUDGET["grad_clip"]  # the norm logged is the one before the clip
    stepped = torch.linalg.vector_norm(torch.stack([p.grad.norm() for p in params]))  # what Adam was given
    assert float(stepped) == pytest.approx(BUDGET["grad_clip"], rel=1e-4)


def _polyak(trajectory, decay):
    """The trainer's EMA (TF warm-up: decay min(d, (1 + n) / (10 + n)) at step n) of a list of parameter lists."""
    ema = [t.clone() for t in trajectory[0]]
    for n, now in enumerate(trajectory[1:], start=1):
        ema = [e + (1 - min(decay, (1 + n) / (10 + n))) * (p - e) for e, p in zip(ema, now)]
    return ema


def test_the_model_is_the_polyak_average_of_the_steps_with_its_warm_up(tmp_path):
    budget = {**BUDGET, "steps": 12}
    objective, (w, v) = toy()
    seen = []
    inner = objective.loss_terms
    objective.loss_terms = lambda b, at: seen.append([w.detach().clone(), v.detach().clone()]) or inner(b, at)
    train(objective, {**budget, "ema_decay": None}, checkpoint_dir=tmp_path / "raw")  # the same steps, not averaged
    trajectory = [*seen, [w.detach().clone(), v.detach().clone()]]
    averaged, params = toy()
    train(averaged, budget, checkpoint_dir=tmp_path / "ema")
    assert all(torch.allclose(p, e, atol=1e-6) for p, e in zip(params, _polyak(trajectory, BUDGET["ema_decay"])))
    assert not torch.allclose(params[0], trajectory[-1][0], atol=1e-3)  # not the last step's weights


def test_a_time_cut_run_with_ema_keeps_the_averaged_weights_of_its_best_checkpoint(tmp_path):
    budget = {**BUDGET, "steps": 50, "checkpoint_every": 1, "ema_decay": 0.9, "max_minutes": 1.0 / 60}
    objective, (w, v) = toy(sleep_s=0.4, slow_from=2, jump_at=2)  # the loss jumps 100x from step 2: earlier is best
    at_step = []
    inner = objective.loss_terms
    objective.loss_terms = lambda b, at: at_step.append([w.detach().clone()]) or inner(b, at)
    res = train(objective, budget, checkpoint_dir=tmp_path)
    losses = [h["loss"] for h in res.history]
    best = losses.index(min(losses))
    assert res.stopped == "time" and best < 2
    (ema,) = _polyak(at_step[: best + 2], 0.9)  # the average after step best + 1
    assert torch.allclose(w, ema, atol=1e-6) and not torch.equal(w, at_step[best + 1][0])


def test_the_lr_decay_follows_the_steps_done_before_each_step_and_the_last_step_still_learns(tmp_path):
    budget = {**BUDGET, "steps": 20, "lr_switch_epoch": None, "lr_decay_fraction": 0.5, "ema_decay": None}
    res = train(toy()[0], budget, checkpoint_dir=tmp_path)
    lrs = [h["lr"] for h in res.history]
    assert lrs == pytest.approx([BUDGET["lr"] * min(1.0, (1 - k / 20) / 0.5) for k in range(20)])
    assert lrs[-1] > 0


def test_a_resumed_time_budget_counts_the_time_trained_before_the_interruption(tmp_path):
    budget = {**BUDGET, "steps": 100, "checkpoint_every": 1, "ema_decay": None, "max_minutes": 3.0 / 60}
    with pytest.raises(KeyboardInterrupt):  # 5 steps of 0.3 s: half the budget
        train(toy(sleep_s=0.3, interrupt_at=5)[0], budget, checkpoint_dir=tmp_path)
    res = train(toy(sleep_s=0.3)[0], budget, checkpoint_dir=tmp_path)
    assert res.resumed_from is not None and res.stopped == "time"
    assert res.train_s < 3.0 + 0.9  # the other half, not a whole budget more


def test_a_resumed_training_remembers_that_its_lr_followed_the_clock(tmp_path):
    budget = {**BUDGET, "steps": 20, "ema_decay": None, "lr_switch_epoch": None, "lr_decay_fraction": 0.5, "max_minutes": 4.0 / 60}
    objective = toy(key="clock", interrupt_at=15)[0]
    inner = objective.loss_terms
    objective.loss_terms = lambda b, at: (time.sleep(2.5) if at.step == 0 else None) or inner(b, at)  # the clock ahead
    with pytest.raises(KeyboardInterrupt):
        train(objective, budget, checkpoint_dir=tmp_path)
    res = train(toy(key="clock")[0], budget, checkpoint_dir=tmp_path)  # from step 15 on the steps are ahead of the clock
    assert res.resumed_from is not None and res.n_steps == 20 and res.stopped == "clock"
