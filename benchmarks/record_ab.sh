#!/bin/bash
# limbctl record on sim3 with 4 burners (same session), --latency-timer 2 (before) vs default (after), interleaved
# Run: OUT_DIR=DIR RUNS="1 2 3 4 5" benchmarks/record_ab.sh (docs/bench_record_gaps.md); a line a run.
root=$(cd "$(dirname "$0")/.." && pwd)
. ${VENV:-$root/.venv}/bin/activate; export PYTHONPATH=${PYTHONPATH:-$root}
out_dir=${OUT_DIR:-/tmp}; cd "$out_dir"
for run in ${RUNS:-1 2}; do
  for mode in before after; do
    pids=""; for i in 1 2 3 4; do python -c "while 1: pass" & pids="$pids $!"; done
    out=$out_dir/cli_${mode}_${run}.limb; rm -f $out
    extra=""; [ $mode = before ] && extra="--latency-timer 2"
    python -m limbctl record --rig sim3 --out $out --duration 12 --no-view $extra > $out_dir/cli_${mode}_${run}.txt 2>&1
    load=$(cut -d' ' -f1 /proc/loadavg)
    for p in $pids; do kill $p; done; wait $pids 2>/dev/null
    python - "$out" "$mode" "$run" "$load" <<'P'
import sys, numpy as np
from limbctl.teach.dataset import load_dataset
t = load_dataset(sys.argv[1]).t; g = np.diff(t)
print(sys.argv[2], sys.argv[3], "load", sys.argv[4], "samples", len(t), "largest gap ms", round(g.max()*1e3), "holes>0.2s", int((g>0.2).sum()), "s in holes", round(float(g[g>0.2].sum()),2))
P
  done
done
