#!/usr/bin/env bash
# Set up everything on a fresh Debian machine, then run the main job (the demo stack).
#
#   bash scripts/setup.sh            # install, then `hamnet up compose/demo.yaml`
#   bash scripts/setup.sh --no-demo  # install only (CI)
#
# Installs the system libraries (libusb-1.0-0 for open3d; EGL and Mesa for MuJoCo's offscreen
# depth rendering of virtual cameras), a virtual environment in .venv,
# the CPU build of PyTorch and the hamnet package with its dev tools. Safe to rerun.
# HAMNET_PYTHON picks the interpreter; HAMNET_TORCH the PyTorch requirement.
set -euo pipefail
cd "$(dirname "$0")/.."

demo=1
[[ "${1:-}" == "--no-demo" ]] && demo=0

python="${HAMNET_PYTHON:-$(command -v python3.11 || command -v python3)}"
"$python" -c 'import sys; assert sys.version_info >= (3, 10), "hamnet needs Python >= 3.10"'

system_packages=(libusb-1.0-0 libegl1 libegl-mesa0 libopengl0 libgl1-mesa-dri)
missing=()
for package in "${system_packages[@]}"; do
  dpkg -s "$package" >/dev/null 2>&1 || missing+=("$package")
done
if ((${#missing[@]})); then
  echo "==> installing system packages: ${missing[*]}"
  sudo=""
  [[ $(id -u) -ne 0 ]] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}"
fi

if [[ ! -x .venv/bin/python ]]; then
  echo "==> creating .venv with $python"
  "$python" -m venv .venv
fi
pip=(.venv/bin/python -m pip --disable-pip-version-check -q)
# The CPU build of PyTorch is pinned here, not in the package metadata: a bare `torch`
# requirement would pull a multi-GB CUDA build onto a machine without a GPU.
echo "==> installing PyTorch (${HAMNET_TORCH:-torch==2.13.0})"
"${pip[@]}" install "${HAMNET_TORCH:-torch==2.13.0}"
echo "==> installing hamnet and its dependencies"
# The reference extra (gymnasium, Stable-Baselines3: a few MB beside MuJoCo, which hamnet
# already needs) lets `bash scripts/test.sh -m slow` run the outside-PPO check. PyTorch is
# named again so that no extra can swap the pinned CPU build for another: pip refuses instead.
"${pip[@]}" install -e '.[dev,reference]' "${HAMNET_TORCH:-torch==2.13.0}"
.venv/bin/python -c 'import open3d, mujoco, pinocchio, ruckig, rerun, mcap, torch, zenoh' \
  || { echo "an installed dependency does not import" >&2; exit 1; }
echo "==> ready: $(.venv/bin/hamnet --version)"

if ((demo)); then
  echo "==> running the main job: hamnet up compose/demo.yaml"
  exec .venv/bin/hamnet up compose/demo.yaml
fi
