#!/usr/bin/env bash
# The checks of the sim's warp backend that need a GPU (issue 32), in a few minutes, for a
# session lent one: the backend against the C engine on the GPU (the same tests as on
# Warp's CPU device), then its speed at 1024 environments against the C engine's.
#   bash scripts/warp_gpu_check.sh            # after bash scripts/setup.sh --no-demo
set -euo pipefail
cd "$(dirname "$0")/.."
HAMNET_WARP_DEVICE=cuda .venv/bin/python -m pytest -q -p no:cacheprovider tests/sim/test_warp_backend.py
.venv/bin/python benchmarks/sim.py --backend warp --quick
