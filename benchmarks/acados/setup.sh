#!/usr/bin/env bash
# The acados environment for benchmarks/acados: acados 0.2.2 (the registry's comma-deps-acados: its libraries, Python
# template and t_renderer, with its own CasADi 3.6.7 vendored) and aerorelay's sources with their other runtime
# dependencies. Never aerorelay's own environment: the two CasADis must not meet.
#
#   bash benchmarks/acados/setup.sh [VENV]      # default: benchmarks/acados/.venv
set -euo pipefail
REPO=$(cd "$(dirname "$0")/../.." && pwd)
VENV=${1:-$REPO/benchmarks/acados/.venv}
PY=${PYTHON:-python3.11}
"$PY" -m venv "$VENV"
"$VENV/bin/pip" install -q "comma-deps-acados==0.2.2.post92"
# aerorelay's runtime dependencies but CasADi (acados' vendored one stands in), then aerorelay without dependencies
mapfile -t DEPS < <("$VENV/bin/python" - "$REPO/pyproject.toml" <<'PY'
import sys, tomllib
for d in tomllib.load(open(sys.argv[1], "rb"))["project"]["dependencies"]:
    if not d.lower().startswith("casadi"):
        print(d)
PY
)
"$VENV/bin/pip" install -q "${DEPS[@]}"
"$VENV/bin/pip" install -q --no-deps -e "$REPO"
"$VENV/bin/python" -c "import acados; acados.smoketest(); import casadi; print('acados environment ready:', '$VENV', '(CasADi', casadi.__version__ + ')')"
