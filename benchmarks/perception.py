"""Perception benchmark: clouds and tokens per second for B environments with and without
the per-episode caches, and the culling sampler against sampling the boolean mesh union of
the same scenes (trimesh + manifold3d), the cached step with the encoder's layers in
float32 against bfloat16 (`CloudConfig.encoder_precision`), and the cached step of objects
being pushed with the local cloud ranked over shortlists against the whole pool every step
(`CloudConfig.local_shortlist`), in one run.

Scenes come from the sim's own `VectorEnv`. "Cached" is one `Perception.step` (pose the
object, local cloud, encode it); "uncached" redoes every episode's scene sampling and the
global and object encodings each step as well. The union baseline builds each scene's
union mesh with manifold3d and samples it with trimesh, one scene at a time (it does not
vectorize), against `sample_surface` for all scenes at once. The pushed objects move 5 mm
a step in a direction of their own, the pace of the scripted pusher's push (2 cm a step at
most); `local_full_ranking_share` is the share of environment steps that ranked the whole
pool anyway. Last line: one JSON object.

    python benchmarks/perception.py [--quick] [--num-envs 64]
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np
import torch
import trimesh

# Run as a script, so benchmarks/ is on sys.path: the helpers every benchmark shares.
from common import durations, report, summary

from hamnet.perception.config import CloudConfig
from hamnet.perception.core import EpisodeScenes, Perception
from hamnet.perception.scene_cloud import sample_surface
from hamnet.perception.unicorn import UniCORN
from hamnet.runtime.compute import native_bfloat16
from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv
from hamnet.sim.quaternion import to_matrix


def union_sample(scene: dict[str, np.ndarray], num_points: int) -> np.ndarray:
    """The baseline: boolean union of one scene's active boxes, then area-weighted samples."""
    boxes = []
    for centre, quat, half in zip(scene["centre"], scene["quat"], scene["half_extent"]):
        transform = np.eye(4)
        transform[:3, :3], transform[:3, 3] = to_matrix(quat), centre
        boxes.append(trimesh.creation.box(extents=2 * half, transform=transform))
    union = trimesh.boolean.union(boxes, engine="manifold")
    points, _ = trimesh.sample.sample_surface(union, num_points)
    return points


def pushed_steps(core: Perception, pose: torch.Tensor, repeats: int) -> np.ndarray:
    """Seconds of `repeats` cached steps, every object moving 5 mm a step in a direction of
    its own (after one warm-up step, which ranks every pool in full)."""
    direction = torch.nn.functional.normalize(torch.randn(len(pose), 3), dim=1)
    direction[:, 2] = 0.0
    moved = pose.clone()

    def step() -> None:
        moved[:, :3] += 0.005 * direction
        core.step(moved)

    return durations(step, repeats)


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="few repeats (under a minute)")
    parser.add_argument("--num-envs", type=int, default=64)
    args = parser.parse_args()
    torch.manual_seed(0)
    torch.set_num_threads(max(torch.get_num_threads(), 1))
    b, repeats = args.num_envs, (3 if args.quick else 20)
    env = VectorEnv(SimConfig(num_envs=b, num_objects=8, nthread=1, seed=0))
    obs = env.reset(seed=0)
    s = env.scenes()
    scenes = EpisodeScenes.from_arrays(s.env_ids, s.episode_ids, s.cuboid_centre, s.cuboid_quat,
                                       s.cuboid_half_extent, s.cuboid_active, s.object_points)  # fmt: skip
    pose = torch.as_tensor(obs.object_pose, dtype=torch.float32)
    config = CloudConfig()
    encoder = UniCORN()
    core = Perception(encoder, b, config)
    core.start_episodes(scenes)
    precisions = {}  # the cached step with the encoder's layers in float32 and in bfloat16
    for precision in ("float32", "bfloat16"):
        fixed = Perception(encoder, b, replace(config, encoder_precision=precision))
        fixed.start_episodes(scenes)
        precisions[precision] = durations(lambda fixed=fixed: fixed.step(pose), repeats)

    pushed = {}  # the cached step of pushed objects with and without shortlists
    for shortlist in (config.local_shortlist, 0):
        moving = Perception(encoder, b, replace(config, local_shortlist=shortlist))
        moving.start_episodes(scenes)
        pushed[shortlist] = (pushed_steps(moving, pose, repeats), moving)
    (short_s, short_core), (full_s, _) = pushed[config.local_shortlist], pushed[0]

    def uncached() -> None:
        core.start_episodes(scenes)
        core.step(pose)

    cached_s = durations(lambda: core.step(pose), repeats)
    uncached_s = durations(uncached, repeats)
    cuboids = scenes.cuboids
    culling_s = durations(lambda: sample_surface(cuboids, config.num_points, config.grid), repeats)
    union_envs = min(b, 8 if args.quick else b)
    rows = [{"centre": s.cuboid_centre[i][s.cuboid_active[i]], "quat": s.cuboid_quat[i][s.cuboid_active[i]],
             "half_extent": s.cuboid_half_extent[i][s.cuboid_active[i]]} for i in range(union_envs)]  # fmt: skip
    union_s = durations(
        lambda: [union_sample(row, config.num_points) for row in rows], max(1, repeats // 3)
    )
    union_per_env = union_s / union_envs
    culling_per_env = culling_s / b
    figures = {
        "num_envs": b,
        "device": "cpu",
        "torch_threads": torch.get_num_threads(),
        "cached_step": summary(cached_s, "ms", 1e3),
        "uncached_step": summary(uncached_s, "ms", 1e3),
        "cached_steps_per_s": 1.0 / float(np.median(cached_s)),
        "uncached_steps_per_s": 1.0 / float(np.median(uncached_s)),
        "cached_env_steps_per_s": b / float(np.median(cached_s)),
        "cache_speedup": float(np.median(uncached_s) / np.median(cached_s)),
        "native_bfloat16": native_bfloat16(),
        "cached_step_float32": summary(precisions["float32"], "ms", 1e3),
        "cached_step_bfloat16": summary(precisions["bfloat16"], "ms", 1e3),
        "encoder_bfloat16_speedup": float(
            np.median(precisions["float32"]) / np.median(precisions["bfloat16"])
        ),
        "local_shortlist": config.local_shortlist,
        "pushed_step_shortlist": summary(short_s, "ms", 1e3),
        "pushed_step_full_ranking": summary(full_s, "ms", 1e3),
        "local_shortlist_speedup": float(np.median(full_s) / np.median(short_s)),
        "local_full_ranking_share": (short_core.local_clouds.full_rankings - b) / (b * repeats),
        "culling_sample_512": summary(culling_s, "ms", 1e3),
        "union_sample_512_per_env_ms": 1e3 * float(np.median(union_per_env)),
        "culling_sample_512_per_env_ms": 1e3 * float(np.median(culling_per_env)),
        "union_envs_timed": union_envs,
        "culling_vs_union_speedup": float(np.median(union_per_env) / np.median(culling_per_env)),
    }
    print(f"{b} environments: cached step {figures['cached_step']['median_ms']:.1f} ms (float32 layers "
          f"{figures['cached_step_float32']['median_ms']:.1f}, bfloat16 {figures['cached_step_bfloat16']['median_ms']:.1f}), pushed objects "
          f"{figures['pushed_step_shortlist']['median_ms']:.1f} ms with shortlists against "
          f"{figures['pushed_step_full_ranking']['median_ms']:.1f} ranking whole pools, uncached "
          f"{figures['uncached_step']['median_ms']:.1f} ms ({figures['cache_speedup']:.1f}x); culling sampler "
          f"{figures['culling_sample_512_per_env_ms']:.2f} ms/env vs union {figures['union_sample_512_per_env_ms']:.2f} ms/env")  # fmt: skip
    return figures


if __name__ == "__main__":
    report(main())
