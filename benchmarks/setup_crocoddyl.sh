#!/usr/bin/env bash
# Create the Crocoddyl benchmark venv used by benchmarks/mpc_vs_crocoddyl.py (idempotent).
#
#   bash benchmarks/setup_crocoddyl.sh            # creates <repo>/.venv-croc
#   CROC_VENV=/some/path bash benchmarks/setup_crocoddyl.sh
#
# Crocoddyl comes from PyPI (`pip install crocoddyl`, which pulls libcrocoddyl, pin and
# example-robot-data). pip resolves pin 4.1.0, with which the crocoddyl 3.2.1 wheel's
# forward dynamics are wrong: its accelerations are those of `pin.aba` without gravity
# (20-50 rad/s^2 off on the Panda), while its derivatives agree. So pin is pinned back to
# 4.0.0 afterwards. The last step checks Crocoddyl's accelerations on the Panda
# against `pin.aba` and fails loudly if they disagree.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/.." && pwd)"
venv="${CROC_VENV:-$repo/.venv-croc}"
python="${PYTHON:-python3}"

if [ ! -x "$venv/bin/python" ]; then
    echo "setup_crocoddyl: creating $venv"
    "$python" -m venv "$venv"
fi
pip=("$venv/bin/python" -m pip --disable-pip-version-check -q)

have() {  # have DIST VERSION-OR-EMPTY: the distribution is installed (at that version)
    local v
    v="$("$venv/bin/python" -c "import importlib.metadata as m; print(m.version('$1'))" 2>/dev/null)" || return 1
    [ -z "${2:-}" ] || [ "$v" = "$2" ]
}

if ! have crocoddyl; then
    echo "setup_crocoddyl: pip install crocoddyl numpy"
    "${pip[@]}" install crocoddyl numpy
fi
if ! have pin 4.0.0; then
    echo "setup_crocoddyl: pip install pin==4.0.0 (crocoddyl's wheel is wrong with pin 4.1.0)"
    "${pip[@]}" install "pin==4.0.0"
fi

# The benchmark's Panda model (benchmarks/mpc_plant.py): with pin 4.1.0 this check reports
# errors of 20-50 rad/s^2; with pin 4.0.0 the two agree to the last bit.
PYTHONPATH="$here" "$venv/bin/python" - <<'PY'
import crocoddyl
import numpy as np
import pinocchio as pin
from mpc_plant import panda_model

model = panda_model()
state = crocoddyl.StateMultibody(model)
act = crocoddyl.ActuationModelFull(state)
costs = crocoddyl.CostModelSum(state, model.nv)
diff = crocoddyl.DifferentialActionModelFreeFwdDynamics(state, act, costs)
data, pdata = diff.createData(), model.createData()
rng = np.random.default_rng(0)
err = 0.0
for _ in range(20):
    q = pin.randomConfiguration(model)
    v, u = rng.normal(size=model.nv), 5.0 * rng.normal(size=model.nv)
    diff.calc(data, np.concatenate([q, v]), u)
    err = max(err, float(np.abs(data.xout - pin.aba(model, pdata, q, v, u)).max()))
print(f"setup_crocoddyl: crocoddyl {crocoddyl.__version__}, pin {pin.__version__}, "
      f"max |a_croc - pin.aba| = {err:.2e} rad/s^2 on the Panda")
if err > 1e-8:
    raise SystemExit("setup_crocoddyl: Crocoddyl's dynamics disagree with pin.aba")
PY
