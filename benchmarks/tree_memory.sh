#!/bin/bash
# Peak memory of a command and every process it starts (the reproduction's training workers), as the
# summed PSS (shared pages split between the processes that map them: the memory the tree really
# holds) and the summed RSS (shared pages counted once per process: an upper bound), sampled every
# 0.5 s from /proc. Threads are not counted twice (pstree -T).
#
#   OMP_NUM_THREADS=1 CTRKIN_NO_PROGRESS=1 bash benchmarks/tree_memory.sh ctrkin reproduce --scale full --out out/full
#
# Prints the command's own output, then a table and one JSON line {"peak_pss_mb": …, "peak_rss_sum_mb": …}.
set -u
"$@" &
root=$!
peak_pss=0; peak_rss=0
while kill -0 "$root" 2>/dev/null; do
  pss=0; rss=0
  for p in $(pstree -pT "$root" 2>/dev/null | grep -o '([0-9]\+)' | tr -d '()'); do
    a=$(awk '/^Pss:/{print $2}' "/proc/$p/smaps_rollup" 2>/dev/null); pss=$((pss + ${a:-0}))
    b=$(awk '/VmRSS/{print $2}' "/proc/$p/status" 2>/dev/null); rss=$((rss + ${b:-0}))
  done
  [ "$pss" -gt "$peak_pss" ] && peak_pss=$pss
  [ "$rss" -gt "$peak_rss" ] && peak_rss=$rss
  sleep 0.5
done
wait "$root"; status=$?
printf '\n%-28s %10s\n' "process tree, peak" "MB"
printf '%-28s %10d\n' "summed PSS" $((peak_pss / 1024)) "summed RSS (upper bound)" $((peak_rss / 1024))
printf '{"peak_pss_mb": %d, "peak_rss_sum_mb": %d, "exit_status": %d}\n' $((peak_pss / 1024)) $((peak_rss / 1024)) "$status"
exit "$status"
