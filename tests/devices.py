"""Device placement checks for the learned methods (issue 60): the devices a test runs on, and a guard that
finds, on any machine, the two mistakes that break a CUDA run.

A CPU-only machine cannot run a CUDA drape, but it can see what breaks one:

1. A tensor made without the run's device: a factory call (``torch.zeros``, ``torch.tensor``, ``torch.randn``,
   ...) in ``drapebench/`` or ``methods/`` that names no ``device`` makes a CPU tensor on any run device.
   :class:`StrayTensors` records those calls (file:line). Calls that take their device from their input
   (``*_like``, ``new_*``, ``torch.as_tensor`` of a tensor), torch's own internals and a network's construction
   (a network is built on the CPU and moved with ``.to(device)``, so its initial weights are the same on every
   device) are not recorded. A tensor meant to live on the CPU names it (``device="cpu"``, the string: a Host
   tensor, below).
2. A CPU tensor used on the device without being moved: the scene's garment, body sequences and reference
   drapes are CPU records, a method moves what it needs to the run's device, and what a CPU stage (libigl, a
   k-d tree) computes comes back. :func:`host` marks a record's tensors as :class:`Host` tensors, whose ``.device``
   reads ``cpu:0``, a device distinct from the run's ``cpu`` (a ``torch.device``) as the CPU is from CUDA; within
   the guard, what the project's code brings to the host (``.cpu()``, ``.to("cpu")``, ``torch.from_numpy``, a
   factory with ``device="cpu"``) is a Host tensor too. An operation that mixes a Host tensor with a run-device
   tensor (both with elements) is recorded, as CUDA would refuse it; ``.to(device)`` of a Host tensor to the run's
   device gives an ordinary tensor, ``.to(dtype)`` keeps it on the host, and neither a tensor indexed by a Host
   index nor a copy between the two (both of which CUDA accepts) is recorded.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import pytest
import torch
from torch.overrides import TorchFunctionMode
from torch.utils._pytree import tree_map

ROOT = Path(__file__).resolve().parents[1]
PROJECT = tuple(str(ROOT / d) + "/" for d in ("drapebench", "methods"))
HOST = torch.device("cpu", 0)  # where a Host tensor says it lives: not the run's torch.device("cpu")

# the devices a device-parametrised test runs on: the CPU always, CUDA where torch sees a GPU
DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
device_params = pytest.mark.parametrize("device", DEVICES)

FACTORIES = {torch.zeros, torch.ones, torch.empty, torch.full, torch.eye, torch.arange, torch.linspace, torch.logspace,
             torch.rand, torch.randn, torch.randint, torch.randperm, torch.tensor, torch.as_tensor, torch.scalar_tensor,
             torch.tril_indices, torch.triu_indices}  # fmt: skip
_GUARDS: list[StrayTensors] = []
_DEVICE = torch._C.TensorBase.__dict__["device"]


def _site() -> tuple[str | None, bool]:
    """The project's file:line that called into torch (None when the caller is not the project's code), and
    whether the call came through a torch module's construction."""
    frame, network = sys._getframe(2), False
    while frame is not None and ("/torch/" in frame.f_code.co_filename or frame.f_code.co_filename == __file__):
        network = network or "/torch/nn/modules/" in frame.f_code.co_filename  # a layer's construction
        if "/torch/optim/" in frame.f_code.co_filename:  # an optimizer's own state (Adam keeps its step count on the host)
            return None, network
        frame = frame.f_back
    if frame is None or not frame.f_code.co_filename.startswith(PROJECT):
        return None, network
    network = network or (frame.f_code.co_name == "__init__" and isinstance(frame.f_locals.get("self"), torch.nn.Module))
    return f"{Path(frame.f_code.co_filename).relative_to(ROOT)}:{frame.f_lineno}", network


def _record(what: str) -> None:
    site, _ = _site()
    if _GUARDS and site is not None:
        entry = f"{site} {what}"
        if entry not in _GUARDS[-1].sites:
            _GUARDS[-1].sites.append(entry)


def _as_host(out):
    return tree_map(lambda t: t.as_subclass(Host) if type(t) is torch.Tensor and not t.is_sparse else t, out)


def _is_host_device(device) -> bool:
    """Whether ``device`` names the host: the string "cpu" (the run's device is a torch.device) or :data:`HOST`."""
    return device == "cpu" or (device is not None and torch.device(device) == HOST)


class StrayTensors(TorchFunctionMode):
    """Within ``with StrayTensors() as stray:``, ``stray.sites`` lists "file:line what" for each tensor factory
    called from the project's code without a ``device``, and each operation there that mixes a :class:`Host`
    tensor with a run-device tensor (once per site)."""

    def __init__(self):
        super().__init__()
        self.sites: list[str] = []

    def __enter__(self):
        _GUARDS.append(self)
        torch.from_numpy = _from_numpy
        return super().__enter__()

    def __exit__(self, *exc):
        _GUARDS.remove(self)
        torch.from_numpy = _FROM_NUMPY
        return super().__exit__(*exc)

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if func is torch.Tensor.cpu or func is torch.Tensor.to and _is_host_device(_target(args[1:], kwargs)):
            out = func(*args, **kwargs)  # a run-device tensor brought to the host by the project's code: a Host tensor
            return _as_host(out) if _site()[0] is not None else out
        if func not in FACTORIES:
            return func(*args, **kwargs)
        if _is_host_device(kwargs.get("device")):  # beside a Host tensor, or named "cpu": on the host
            return _as_host(func(*args, **{**kwargs, "device": "cpu"}))
        if args and type(args[0]) is Host:  # torch.as_tensor(host, ...): on the host unless moved to a device
            out = func(args[0].as_subclass(torch.Tensor), *args[1:], **kwargs)
            return out if kwargs.get("device") is not None else _as_host(out)
        if kwargs.get("device") is None and not (func is torch.as_tensor and isinstance(args[0], torch.Tensor)):
            site, network = _site()
            if site is not None and not network and f"{site} torch.{func.__name__}" not in self.sites:
                self.sites.append(f"{site} torch.{func.__name__}")
        return func(*args, **kwargs)


def _target(args, kwargs):
    """The device a ``Tensor.to`` call names (a tensor argument: that tensor's; "cpu": :data:`HOST`), or None."""
    for a in (*args, kwargs.get("device"), kwargs.get("other")):
        if isinstance(a, torch.Tensor):
            return HOST if type(a) is Host else a.device
        if isinstance(a, (torch.device, str)):
            return HOST if _is_host_device(a) else torch.device(a)
    return None


_FROM_NUMPY = torch.from_numpy


def _from_numpy(array):
    """``torch.from_numpy`` in a guard: a Host tensor when the project's code calls it (it is on the host)."""
    out = _FROM_NUMPY(array)
    return _as_host(out) if _site()[0] is not None else out


class Host(torch.Tensor):
    """A tensor of a CPU record (garment, body sequence, reference drape) in a device test (module docstring)."""

    @classmethod
    def __torch_function__(cls, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if getattr(func, "__self__", None) is _DEVICE:
            return HOST
        if func is torch.Tensor.cpu:
            return args[0]
        with torch._C.DisableTorchFunctionSubclass():
            if func is torch.Tensor.to or func is torch.Tensor.cuda or func in FACTORIES:
                device = {torch.Tensor.to: lambda: _target(args[1:], kwargs), torch.Tensor.cuda: lambda: torch.device("cuda")}.get(
                    func, lambda: _target((), kwargs))()  # fmt: skip
                if device is not None and device != HOST:  # moved to the run's device (on the CPU: the same storage)
                    return tree_map(lambda t: t.as_subclass(torch.Tensor) if type(t) is Host else t, func(*args, **kwargs))
                kwargs = {k: ("cpu" if _is_host_device(v) else v) for k, v in kwargs.items()}
                args = tuple("cpu" if isinstance(a, (torch.device, str)) and _is_host_device(a) else a for a in args)
            tensors = [t for t in _flat((args, kwargs)) if isinstance(t, torch.Tensor)]
            host = any(type(t) is Host and t.dim() > 0 for t in tensors)
            device = any(type(t) is not Host and t.dim() > 0 for t in tensors)
            indexed = func is torch.Tensor.__getitem__ and type(args[0]) is not Host  # CUDA takes host indices
            copied = func in (torch.Tensor.__setitem__, torch.Tensor.copy_)  # a copy crosses devices
            out = func(*args, **kwargs)
        if host and device and not (indexed or copied):
            _record(f"{getattr(func, '__name__', func)} mixes a CPU tensor (not moved) with the run's device")
        if func is torch.Tensor.numpy or func is torch.Tensor.tolist or func is torch.Tensor.item:
            return out
        if host and not device or not device and any(type(t) is Host for t in tensors):
            return _as_host(out)
        return out


def _flat(obj):
    if isinstance(obj, (list, tuple)):
        for o in obj:
            yield from _flat(o)
    elif isinstance(obj, dict):
        for o in obj.values():
            yield from _flat(o)
    else:
        yield obj


def host(record):
    """A copy of a CPU record (garment, :class:`~drapebench.body.BodySequence`, topology, tensor or a namespace of
    them) whose tensors are :class:`Host` tensors."""
    if isinstance(record, torch.Tensor):
        return _as_host(record)
    if isinstance(record, tuple):
        return tuple(host(r) for r in record)
    if dataclasses.is_dataclass(record):
        changes = {f.name: host(getattr(record, f.name)) for f in dataclasses.fields(record)
                   if f.init and (isinstance(getattr(record, f.name), (torch.Tensor, tuple)) or dataclasses.is_dataclass(getattr(record, f.name)))}  # fmt: skip
        return dataclasses.replace(record, **changes)
    if hasattr(record, "__dict__"):
        copy = type(record).__new__(type(record))
        copy.__dict__.update({k: host(v) if isinstance(v, torch.Tensor) or dataclasses.is_dataclass(v) else v for k, v in vars(record).items()})
        return copy
    return record
