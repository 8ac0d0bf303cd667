#!/usr/bin/env bash
# Run the quick eval, the loop benchmark and the envelope benchmark on two revisions of this
# repository, one after the other on the same machine, and compare what must not change.
#
#   bash benchmarks/before_after.sh BEFORE_REV [AFTER_REV] [OUT_DIR]
#
# Each revision is checked out into its own git worktree under OUT_DIR and imported from there
# (PYTHONPATH), with this checkout's virtual environment (.venv). Results: OUT_DIR/{eval_,loop_,
# envelope_}{before,after}*; the accuracy comparison is printed at the end (timings are printed
# side by side: on a shared machine compare the ratios each run reports, not the times).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
before=${1:?usage: before_after.sh BEFORE_REV [AFTER_REV] [OUT_DIR]}
after=${2:-HEAD}
out=${3:-$(mktemp -d)}
py="$here/.venv/bin/python"
mkdir -p "$out"
for side in before after; do
  rev=$([ "$side" = before ] && echo "$before" || echo "$after")
  rm -rf "$out/tree_$side"
  git -C "$here" worktree add -f --detach "$out/tree_$side" "$rev" >/dev/null
done
run() {  # side, command...
  local side=$1
  shift
  (cd "$out/tree_$side" && PYTHONPATH="$out/tree_$side" "$@")
}
for side in before after; do
  echo "eval --quick ($side)"
  run "$side" "$py" -c "import sys; from limbctl.cli import main; sys.exit(main())" \
    eval --quick --out "$out/eval_$side" >"$out/eval_$side.log" 2>&1
  echo "bench_loop ($side)"
  run "$side" "$py" benchmarks/bench_loop.py --out "$out/loop_$side.md" >"$out/loop_$side.log" 2>&1
  echo "bench_envelope ($side)"
  run "$side" "$py" benchmarks/bench_envelope.py --out "$out/envelope_$side.md" \
    >"$out/envelope_$side.log" 2>&1
done
echo "== quick eval: summary tables (identical when nothing printed)"
diff "$out/eval_before/summary.md" "$out/eval_after/summary.md" || true
echo "== quick eval: every run's figures without its cache key and fit time (identical when nothing printed)"
# column 1 is the run's cache key, which holds the region's FIT_VERSION: a raised version changes
# every key though no figure moved; column 19 is the fit time
diff <(cut -d, -f2-18 "$out/eval_before/runs.csv" | sort) \
  <(cut -d, -f2-18 "$out/eval_after/runs.csv" | sort) || true
echo "== quick eval: the three-servo twist trial"
diff "$out/eval_before/twist.md" "$out/eval_after/twist.md" || true
echo "== envelope accuracy rows, the last column (fit seconds) dropped"
strip() { grep '^| ' "$1" | grep -v ' ms \| us \| s |' | sed -E 's/\| [0-9.]+ \|$/|/'; }
diff <(strip "$out/envelope_before.md") <(strip "$out/envelope_after.md") || true
echo "== loop"
grep '^| ' "$out/loop_before.md" | sed 's/^/before /'
grep '^| ' "$out/loop_after.md" | sed 's/^/after  /'
for side in before after; do git -C "$here" worktree remove --force "$out/tree_$side"; done
echo "results in $out"
