#!/usr/bin/env bash
# Run the test suite (12-16 minutes on 2 cores). Extra arguments go to pytest, e.g.
# `bash scripts/test.sh -m slow` for the long learning runs and soak tests.
# `bash scripts/test.sh --fast` leaves out the tests that start hamnet processes (marked
# `stack`), run the benchmarks (`benchmark`) or step MuJoCo Warp (`warp`): the loop to run
# while changing code.
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ ! -x .venv/bin/python ]]; then
  echo "no .venv: run 'bash scripts/setup.sh --no-demo' first" >&2
  exit 1
fi
selection="not slow"
if [[ "${1:-}" == "--fast" ]]; then
  selection="not slow and not stack and not benchmark and not warp"
  shift
fi
status=0
.venv/bin/python -m pytest -m "$selection" "$@" || status=$?
# pytest exits 5 when a selection matches no test: not a failure of the suite.
if ((status == 5)); then
  echo "no tests matched the selection"
  status=0
fi
exit "$status"
