"""Training of the learned methods: one loop (:func:`train`), its learning-rate schedule and checkpoints."""

from drapebench.train.checkpoint import load_state, save_state
from drapebench.train.schedule import STOPS, clock_driven, combined_stop, scheduled_lr
from drapebench.train.trainer import Objective, Step, TrainResult, train, train_config, write_logs

__all__ = ["STOPS", "Objective", "Step", "TrainResult", "load_state", "save_state", "clock_driven", "combined_stop", "scheduled_lr", "train", "train_config", "write_logs"]
