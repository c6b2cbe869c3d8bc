"""Where learned methods run: device checks, torch threads, and the machine's own description.

* :func:`check_device` — ``"cpu"``, ``"cuda"``, ``"cuda:N"``, ``"mps"``
  validated against this machine (one clear error, e.g. ``cuda:7`` on a
  CPU-only box);
* :func:`set_threads` — torch's intra-op threads for this process
  (:data:`DEFAULT_CPU_THREADS` when not given and the device is the CPU:
  one thread per process measured faster for SJDD-Net inference on a shared
  2-core machine, ``benchmarks/results/threads.md``);
* :func:`machine_info` / :func:`describe_machine` — CPU model, cores, memory,
  torch threads and GPUs, read from the machine itself for reports;
* :func:`check_ensemble` — the ``ensemble`` option of learned methods
  (views of :func:`spikejdd.models.run_ensemble`).
"""

from __future__ import annotations

import os
import platform
import sys
from pathlib import Path

import numpy as np

from spikesim.errors import bad_value

__all__ = ["check_device", "set_threads", "configure", "machine_info", "describe_machine",
           "DEFAULT_CPU_THREADS", "ENSEMBLES", "check_ensemble"]

#: torch threads per process on the CPU when ``threads`` is not given.
DEFAULT_CPU_THREADS = 1
#: Views of the geometric self-ensemble (:func:`spikejdd.models.run_ensemble`):
#: 1 the input alone, 2 with its transpose, 4 with the 180° rotations of both.
ENSEMBLES = (1, 2, 4)


def check_ensemble(ensemble, default: int | None = None) -> int | None:
    """``ensemble`` validated: one of :data:`ENSEMBLES`; None gives ``default``
    (None itself where no default is given: the option was not set)."""
    if ensemble is None:
        return default
    if (isinstance(ensemble, bool) or not isinstance(ensemble, (int, np.integer))
            or ensemble not in ENSEMBLES):
        raise bad_value("ensemble", ensemble, "1 (the input alone), 2 (with its transpose) or 4 "
                                              "(with the 180° rotations too); None: the "
                                              "method's default")
    return int(ensemble)


def check_device(device: str | None, name: str = "device") -> str:
    """Validated torch device name (``None`` = ``"cpu"``); raises naming what exists here
    (``name``: how the error names the setting, e.g. ``"--device"`` on a command line)."""
    if device is None:
        return "cpu"
    import torch

    try:
        dev = torch.device(str(device).strip())
    except (RuntimeError, ValueError):
        raise bad_value(name, device, "cpu, cuda, cuda:N or mps") from None
    if dev.type == "cpu":
        return "cpu"
    if dev.type == "cuda":
        n = torch.cuda.device_count() if torch.cuda.is_available() else 0
        index = 0 if dev.index is None else dev.index
        if index >= n:
            have = f"CUDA devices cuda:0..cuda:{n - 1}" if n else "no CUDA device"
            raise bad_value(name, device, f"a device this machine has ({have}; use cpu)")
        return f"cuda:{index}"
    if dev.type == "mps":
        if not (getattr(torch.backends, "mps", None) and torch.backends.mps.is_available()):
            raise bad_value(name, device, "a device this machine has (no MPS; use cpu)")
        return "mps"
    raise bad_value(name, device, "cpu, cuda, cuda:N or mps")


def set_threads(threads: int | None, device: str = "cpu") -> int:
    """Set torch's intra-op threads; ``None`` = :data:`DEFAULT_CPU_THREADS` on the CPU
    (torch's own default elsewhere).  Returns the number in effect.

    numba's thread pool is started first: under numba's OpenMP layer, starting it
    (at a process's first parallel kernel, e.g. the first simulation) sets the
    OpenMP thread count that torch shares, and would undo this setting."""
    import numba
    import torch

    numba.get_num_threads()  # starts numba's threading layer, if not yet started

    if threads is None:
        if str(device) != "cpu":
            return torch.get_num_threads()
        threads = DEFAULT_CPU_THREADS
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise bad_value("threads", threads, "an integer >= 1 torch threads per process")
    torch.set_num_threads(threads)
    return torch.get_num_threads()


def configure(device: str | None = None, threads: int | None = None) -> tuple[str, int]:
    """:func:`check_device` then :func:`set_threads`; returns ``(device, threads)``."""
    dev = check_device(device)
    return dev, set_threads(threads, dev)


def _cpuinfo() -> tuple[str | None, int | None]:
    """CPU model name and physical core count from /proc/cpuinfo (Linux), else None."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return None, None
    model, cores, phys = None, set(), None
    for block in text.split("\n\n"):
        fields = {}
        for line in block.splitlines():
            key, _, value = line.partition(":")
            fields[key.strip()] = value.strip()
        model = model or fields.get("model name") or fields.get("Model") or fields.get("cpu")
        if "core id" in fields:
            phys = fields.get("physical id", "0")
            cores.add((phys, fields["core id"]))
    return model, (len(cores) or None)


def _memory_gib() -> float | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return int(line.split()[1]) / 2**20
    except (OSError, ValueError, IndexError):
        pass
    return None


def machine_info() -> dict:
    """The machine as it describes itself (no fixed text): CPU, cores, memory, torch, GPUs."""
    model, physical = _cpuinfo()
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    info = {
        "cpu_model": model or platform.processor() or platform.machine() or "unknown",
        "logical_cpus": os.cpu_count(), "usable_cpus": usable, "physical_cores": physical,
        "memory_gib": _memory_gib(), "os": platform.platform(), "python":
        platform.python_version(), "machine": platform.machine(),
    }
    try:
        info["load_average_1min"] = os.getloadavg()[0]
    except (AttributeError, OSError):
        pass
    torch = sys.modules.get("torch")
    if torch is None:
        try:
            import torch
        except ImportError:
            torch = None
    if torch is not None:
        info["torch"] = str(torch.__version__)
        info["torch_threads"] = torch.get_num_threads()
        gpus = []
        if torch.cuda.is_available():
            for i in range(torch.cuda.device_count()):
                p = torch.cuda.get_device_properties(i)
                gpus.append(f"cuda:{i} {p.name} ({p.total_memory / 2**30:.0f} GiB)")
        info["gpus"] = gpus
    return info


def describe_machine(info: dict) -> str:
    """One line for reports, e.g. ``AMD EPYC 7B13, 2 logical CPUs (2 usable), 7.8 GiB, ...``."""
    parts = [info.get("cpu_model", "unknown CPU")]
    cpus = f"{info.get('logical_cpus')} logical CPUs ({info.get('usable_cpus')} usable"
    if info.get("physical_cores"):
        cpus += f", {info['physical_cores']} physical cores"
    parts.append(cpus + ")")
    if info.get("memory_gib"):
        parts.append(f"{info['memory_gib']:.1f} GiB RAM")
    if "torch_threads" in info:
        parts.append(f"torch {info.get('torch')} with {info['torch_threads']} thread(s)")
    gpus = info.get("gpus")
    if gpus is not None:
        parts.append("GPU: " + ("; ".join(gpus) if gpus else "none"))
    if info.get("load_average_1min") is not None:
        parts.append(f"1-min load average {info['load_average_1min']:.2f} while measuring")
    parts.append(f"{info.get('os')}, Python {info.get('python')}")
    return "; ".join(parts)
