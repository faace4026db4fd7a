"""`benchmarks/sim.py --quick` runs to the end and reports the figures its issue names."""

from __future__ import annotations

from tests.benchmarks.quick import run_quick


def test_quick_run_ends_with_one_json_line_of_figures() -> None:
    figures = run_quick("sim.py")
    assert figures["ratio_vs_raw"] > 0 and figures["thread_scaling"] > 0
    assert figures["env_steps_per_s_64"] > 0 and 0 <= figures["reset_share_64"] < 1
    rows = {(row["num_envs"], row["nthread"]): row for row in figures["results"]}
    assert set(rows) == {(n, t) for n in (1, 16, 64) for t in (1, 2)}
    for row in rows.values():
        for path in ("raw", "ours"):
            measured = row[path]
            assert measured["physics_steps_per_s"] > 0 and measured["step_p99_ms"] > 0
    assert rows[(64, 2)]["ours"]["resets"] > 0  # episodes really ended and were drawn again


def test_the_warp_backend_says_when_there_is_no_gpu_and_measures_on_the_cpu() -> None:
    """With no CUDA device the warp run reports why it measured nothing and exits 0; on
    Warp's CPU device it measures both backends at the count asked."""
    import warp as wp

    figures = run_quick("sim.py", 240, "--backend", "warp")
    assert figures["backend"] == "warp" and figures["device"] == "cuda"
    if wp.get_cuda_device_count() == 0:
        assert figures["not_measured"] == "no CUDA device on this machine"
    else:
        assert figures["env_steps_per_s_1024"] > 0
    cpu = run_quick(
        "sim.py", 600, "--backend", "warp", "--warp-device", "cpu", "--warp-num-envs", "2"
    )
    assert cpu["env_steps_per_s_2"] > 0 and 0 < cpu["warp_vs_mujoco_2"]
    assert set(cpu["results"]["2"]) == {"warp", "mujoco"}
