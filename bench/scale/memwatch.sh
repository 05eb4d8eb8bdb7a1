#!/bin/bash
# memwatch.sh LOG CMD...: runs CMD, samples its VmPeak/VmSize/VmHWM/VmRSS (/proc) every 2 s into
# LOG with the seconds since the start; CMD's output goes to LOG.out, its exit status ends LOG.
# Used for the address-space figures of docs/benchmarks.md ("Whole-brain tractograms").
LOG=$1; shift
start=$(date +%s.%N)
"$@" > "$LOG.out" 2>&1 &
P=$!
sleep 0.2
# The measured process: CMD's child when CMD is a wrapper (/usr/bin/time, prlimit).
C=$(pgrep -P $P | head -1); [ -z "$C" ] && C=$P
C2=$(pgrep -P $C | head -1); [ -n "$C2" ] && C=$C2
while kill -0 $P 2>/dev/null; do
  t=$(echo "$(date +%s.%N) - $start" | bc)
  echo "$t $(grep -E 'VmRSS|VmSize|VmHWM|VmPeak' /proc/$C/status 2>/dev/null | tr -s ' \t' ' ' | tr '\n' ' ')" >> "$LOG"
  sleep 2
done
wait $P; echo "rc=$?" >> "$LOG"
