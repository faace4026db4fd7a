"""Keep large message buffers in the process heap.

glibc serves allocations above a threshold (128 KiB at first) with fresh memory maps and
gives freed memory back to the OS. A service that decodes a 400 KB point cloud or a 4 MB
payload every step then faults every page of each buffer in again, which costs far more
than the copy itself (measured by `benchmarks/transport.py`). Raising the mmap and trim
thresholds once at start keeps those buffers' pages in the heap for reuse.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

M_TRIM_THRESHOLD = -1
"""mallopt parameter: free memory at the heap top above this is returned to the OS."""
M_MMAP_THRESHOLD = -3
"""mallopt parameter: allocations above this get their own memory map."""


def keep_large_buffers(mmap_threshold: int = 32 << 20, trim_threshold: int = 256 << 20) -> bool:
    """Raise glibc's mmap and trim thresholds for this process.

    Args:
        mmap_threshold: bytes; allocations up to this come from the heap (4 MB payloads
            and their copies included).
        trim_threshold: bytes of free heap kept before memory is returned to the OS.

    Returns:
        True when applied; False where the C library is not glibc (nothing changes then).
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    return bool(mallopt(M_MMAP_THRESHOLD, mmap_threshold) and mallopt(M_TRIM_THRESHOLD, trim_threshold))
