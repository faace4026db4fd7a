"""Where the services that run networks (perception, policy) compute: torch device and
CPU threads.

Several such services share the cores of one machine, and torch's default of one intra-op
thread per core makes them oversubscribe it: measured on the 2-core demo stack, one thread
each ran the loop 30% faster than the default and removed the watchdog stops that the
slowdown caused at episode resets. A service alone on a big machine can take more.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Literal

import torch

Precision = Literal["auto", "float32", "bfloat16"]
"""How a network runs (UniCORN's inference, PPO's update): "auto" is bfloat16 on a CPU that multiplies bfloat16
natively (`native_bfloat16`) and float32 elsewhere (a GPU, or a CPU that would emulate it
slower than float32)."""


def torch_device(device: str, threads: int) -> torch.device:
    """Use `threads` CPU threads for torch in this process and check that `device` exists.

    Args:
        device: torch device name (cpu, cuda, cuda:1, ...).
        threads: intra-op threads of torch on the CPU (>= 1).
    Raises:
        ValueError: `threads` < 1, or `device` is not a device of this machine.
    """
    if threads < 1:
        raise ValueError(f"threads must be >= 1, got {threads}")
    torch.set_num_threads(threads)
    resolved = torch.device(device)
    if resolved.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"device {device!r} asked for, but this machine has no CUDA device")
    return resolved


@contextmanager
def torch_threads(threads: int) -> Iterator[None]:
    """Run the block on `threads` intra-op threads of torch, then go back to the process's
    setting: a trainer learns on every core while its rollouts wait for the update, and acts
    on one thread while physics takes the other (`RunConfig.learner_threads`)."""
    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def bfloat16_autocast(enabled: bool = True, device_type: str = "cpu") -> torch.autocast:
    """bfloat16 autocast on the CPU (`PPOConfig.precision`, UniCORN's inference under
    `CloudConfig.encoder_precision`) or `device_type`, without autocast's cache of cast
    weights: an update steps the float32 weights inside the block, and the cache kept
    serving the bfloat16 copies made before the first step, so every later pass, the KL
    stop's included, read the old weights (measured on the shipped teacher's batch: the
    update read a KL of 0.020 after keeping 3 actor steps, where the policy had moved 0.068
    on the whole batch; float32's readings matched its policy)."""
    return torch.autocast(device_type, dtype=torch.bfloat16, enabled=enabled, cache_enabled=False)


@functools.cache
def native_bfloat16() -> bool:
    """Whether this machine's CPU multiplies bfloat16 matrices natively (the AVX-512 BF16 or
    AMX flags Linux reports): there oneDNN runs bfloat16 matrix products about twice as fast
    as float32 (UniCORN's layers: 2.3x on 64 local clouds, one thread); without them it
    emulates bfloat16, slower than float32. False where /proc/cpuinfo cannot be read."""
    try:
        flags = Path("/proc/cpuinfo").read_text()
    except OSError:
        return False
    return re.search(r"\b(avx512_bf16|amx_bf16)\b", flags) is not None


def use_bfloat16(precision: Precision, device: torch.device) -> bool:
    """Whether a network asked to run at `precision` on `device` runs in bfloat16."""
    if precision == "auto":
        return device.type == "cpu" and native_bfloat16()
    return precision == "bfloat16"
