"""`torch_device`: thread count applied, impossible devices refused at start-up."""

from __future__ import annotations

import pytest
import torch

from hamnet.runtime.compute import torch_device


def test_threads_are_applied_and_the_device_resolved() -> None:
    before = torch.get_num_threads()
    try:
        assert torch_device("cpu", 1) == torch.device("cpu")
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(before)


def test_bad_threads_or_a_missing_cuda_device_are_refused() -> None:
    with pytest.raises(ValueError, match="threads"):
        torch_device("cpu", 0)
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="no CUDA device"):
            torch_device("cuda", 1)
    with pytest.raises(RuntimeError):
        torch_device("tpu-that-does-not-exist", 1)
