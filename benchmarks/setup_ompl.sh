#!/usr/bin/env bash
# Create (or reuse) the venv that runs OMPL (the referee of benchmarks/planning_ompl.py):
# ompl 2.0.1 and the Pinocchio of geosyn's uv.lock, nothing of geosyn. Idempotent: an
# existing venv with both importable is left alone.
# Usage: bash benchmarks/setup_ompl.sh   (from the repo root or anywhere)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${OMPL_VENV:-$ROOT/.venv-ompl}"
OMPL_VERSION="${OMPL_VERSION:-2.0.1}"
PIN_VERSION="$(sed -n '/^name = "pin"$/{n;s/^version = "\(.*\)"$/\1/p;q}' "$ROOT/uv.lock")"

if [ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c "import ompl, pinocchio" 2>/dev/null; then
    echo "ompl venv ready: $VENV"
    exit 0
fi
"${PYTHON:-python3}" -m venv "$VENV"
"$VENV/bin/python" -m pip install --quiet "ompl==$OMPL_VERSION" "pin==$PIN_VERSION" numpy
"$VENV/bin/python" -c "import ompl, pinocchio; print('ompl venv ready:', '$VENV')"
