"""The allocator tuning every `hamnet` process applies at start."""

from __future__ import annotations

import platform

import pytest

from hamnet.runtime.allocator import keep_large_buffers


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt is glibc's")
def test_glibc_takes_the_thresholds() -> None:
    assert keep_large_buffers()
