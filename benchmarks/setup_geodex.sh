#!/usr/bin/env bash
# Create (or reuse) the Python >= 3.12 venv that runs pygeodex (imports as `geodex`) for
# benchmarks/planning.py. Idempotent: an existing venv with geodex importable is left alone.
# Usage: bash benchmarks/setup_geodex.sh   (from the repo root or anywhere)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${GEODEX_VENV:-$ROOT/.venv-geodex}"
PYGEODEX_VERSION="${PYGEODEX_VERSION:-1.0.0}"

if [ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c "import geodex" 2>/dev/null; then
    echo "geodex venv ready: $VENV ($("$VENV/bin/python" -c 'import importlib.metadata as m; print("pygeodex", m.version("pygeodex"))'))"
    exit 0
fi

# pygeodex needs Python >= 3.12: take the first interpreter that is new enough.
PY=""
for cand in "${PYTHON312:-}" python3.13 python3.12 "$HOME/.pyenv/versions/3.12.1/bin/python3.12" \
    $(ls -d "$HOME"/.pyenv/versions/3.1[2-9]*/bin/python3 2>/dev/null || true) python3; do
    [ -n "$cand" ] || continue
    if command -v "$cand" >/dev/null 2>&1 &&
        "$cand" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 12) else 1)' 2>/dev/null; then
        PY="$cand"
        break
    fi
done
if [ -z "$PY" ]; then
    echo "setup_geodex.sh: no Python >= 3.12 found (pygeodex needs it); set PYTHON312=/path/to/python3.12" >&2
    exit 1
fi

"$PY" -m venv "$VENV"
"$VENV/bin/python" -m pip install --quiet --upgrade pip
"$VENV/bin/python" -m pip install --quiet "pygeodex==$PYGEODEX_VERSION"
"$VENV/bin/python" -c "import geodex; print('geodex venv ready:', '$VENV')"
