"""Helpers of the camera tests: synthetic views and listening for frames on the wire."""

from __future__ import annotations

import time

import numpy as np

from hamnet.camera.frames import decode_frames
from hamnet.camera.views import DepthView
from hamnet.proto.camera_pb2 import DepthFrames
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox

FRAMES = contract.topic("camera/<w>/frames")


def views(count: int = 2, labels: bool = True) -> list[DepthView]:
    """`count` small views with distinct depths, poses and (optionally) labels."""
    rng = np.random.default_rng(0)
    out = []
    for i in range(count):
        pose = np.eye(4)
        pose[:3, 3] = (i, 0.5, 1.0)
        k = np.array([[100.0 + i, 0, 15.5], [0, 100.0, 11.5], [0, 0, 1]])
        depth = rng.uniform(0.5, 2.0, (24, 32)).astype(np.float32)
        mask = rng.integers(0, 3, (24, 32)).astype(np.uint8) if labels else None
        out.append(DepthView(depth, mask, k, pose))
    return out


def listen(session, namespace: str) -> Inbox:
    """An inbox receiving the decoded frames (`DepthFrames`) of worker 0."""
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("frames", FRAMES.key(namespace, w="0"), DepthFrames)
    return inbox


def first_frames(inbox: Inbox, processes, timeout_s: float, tick=None) -> DepthFrames:
    """The first DepthFrames to arrive (calling `tick()` while waiting), failing when a
    process exits or `timeout_s` passes."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for process in processes:
            assert process.poll() is None, process.stdout.read()
        if tick is not None:
            tick()
        received = inbox.get(timeout=0.2)
        if received is not None:
            decode_frames(received.value)  # well formed
            return received.value
    raise AssertionError(f"no frames within {timeout_s} s")
