#!/usr/bin/env bash
# A read-only install run by a user whose home cannot be written: limbctl info, record, train
# and teleop on the embedded simulator, then a list of anything written under the install or HOME
# (there should be nothing). Needs root for `unshare --user` (the commands run as uid 1000, for
# whom the copied install is read-only; root itself ignores file permissions).
#
# Usage: bash benchmarks/readonly_check.sh [PYTHON]   (default: .venv/bin/python of this clone)
set -u
ROOT=$(cd "$(dirname "$0")/.." && pwd)
PY=${1:-$ROOT/.venv/bin/python}
T=$(mktemp -d /tmp/limbctl_ro_XXXX)
chmod 755 "$T"
mkdir "$T/tree" "$T/home" "$T/out"
for d in limbctl calib firmware_sim; do cp -r "$ROOT/$d" "$T/tree/"; done
find "$T/tree" -name __pycache__ -prune -exec rm -rf {} +
chmod 777 "$T/out"
chmod -R a-w "$T/tree" "$T/home"
touch "$T/out/.start"
run() {
  (cd "$T/out" && /usr/bin/time -f "%e s wall, %U+%S s CPU" \
    env -u NUMBA_CACHE_DIR -u XDG_CACHE_HOME HOME="$T/home" PYTHONPATH="$T/tree" \
    PYTHONDONTWRITEBYTECODE=1 unshare --user --map-user=1000 --map-group=1000 \
    "$PY" -m limbctl "$@")
  echo "exit $?"
}
echo "== limbctl info"; run info < /dev/null 2>&1 | tail -3
echo "== limbctl record --duration 15"; run record --duration 15 --out "$T/out/t.limb" < /dev/null 2>&1 | tail -3
echo "== limbctl train"; run train "$T/out/t.limb" --out "$T/out/m.npz" < /dev/null 2>&1 | tail -3
echo "== limbctl teleop (two commands on stdin)"
printf '{"pan": 5, "tilt": 5}\n{"pan": 10, "tilt": 0}\n' | run teleop --model "$T/out/m.npz" --source stdin 2>&1 | tail -4
echo "== files written under the install or HOME (none expected):"
find "$T/tree" "$T/home" -newer "$T/out/.start" -type f
chmod -R u+w "$T"
rm -rf "$T"
