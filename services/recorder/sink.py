"""The file under an MCAP writer: bytes reach the operating system only when the writer
flushes (a closed chunk, the header, the summary), so a write that fails (a full disk)
can be undone back to the last complete record.

Consumes the writer's `write`/`flush`/`tell` calls; produces a file that always ends on a
record boundary once `abandon` has cut off a failed flush: the sequential reader reads it
to its last chunk, with no torn record at its end.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path


class FileSink:
    """A write-only file that buffers until `flush`, and can be cut back to its last flush."""

    def __init__(self, path: Path) -> None:
        """Create `path`; never replaces a regular file (FileExistsError), but writes to an
        existing FIFO or device as it is.

        Raises:
            OSError: the file cannot be created or opened.
        """
        flags = os.O_WRONLY | os.O_CLOEXEC
        if not (path.exists() and not path.is_file()):
            flags |= os.O_CREAT | os.O_EXCL
        self.path = path
        self._fd = os.open(path, flags, 0o644)
        self._regular = stat.S_ISREG(os.fstat(self._fd).st_mode)
        self._pending = bytearray()
        self.flushed = 0
        """Bytes handed to the OS by complete flushes: the file's last record boundary."""

    def write(self, data: bytes) -> int:
        """Buffer `data` until the next flush."""
        self._pending += data
        return len(data)

    def tell(self) -> int:
        """Bytes written so far, buffered ones included (the writer's record offsets)."""
        return self.flushed + len(self._pending)

    def flush(self) -> None:
        """Hand every buffered byte to the OS (no fsync).

        Raises:
            OSError: a write failed (ENOSPC...); the buffered bytes are kept, `flushed` is not
                moved, and the file may hold part of them until `abandon`.
        """
        view = memoryview(self._pending)
        done = 0
        try:
            while done < len(view):
                done += os.write(self._fd, view[done:])
        finally:
            view.release()
        self.flushed += done
        self._pending.clear()

    def close(self) -> None:
        """Flush and close.

        Raises:
            OSError: the last flush failed (the file is still open: call `abandon`).
        """
        self.flush()
        os.close(self._fd)
        self._fd = -1

    def abandon(self) -> bool:
        """Close without writing more: drop the buffered bytes and cut what a failed flush
        wrote, so the file ends on its last record boundary. A file holding nothing is
        removed. Does nothing to a file already closed.

        Returns:
            Whether the file was removed.
        """
        if self._fd < 0:
            return False
        self._pending.clear()
        if self._regular:
            os.ftruncate(self._fd, self.flushed)  # frees space: works on a full disk
        os.close(self._fd)
        self._fd = -1
        if self._regular and self.flushed == 0:
            self.path.unlink(missing_ok=True)
            return True
        return False
