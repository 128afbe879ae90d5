#!/usr/bin/env bash
# The cost of binomial weights against uniform ones, by patch size: user
# CPU seconds of `convert --units map --product slope --border clamp -n N
# --weights W` on a DEM (default bench/.work/dem4096.tif, which
# bench/terrain.sh makes), at N = 3, 9, 33, 63, 255 (or $SIZES). From
# N = 37 on binomial sums are made by FFT in blocks (src/fit/convolve.rs),
# below it outright: this is how that crossover was measured.
#
#   bench/weights.sh [dem.tif]                       # target/release/normalfit
#   BIN=/path/normalfit BASELINE=/path/other/normalfit bench/weights.sh
#                     # another build's times beside, run in turn with
#                     # these (one load for both)
#
# Prints a Markdown table (best of $REPS runs, default 1) and the load
# average: the machine may be shared, so compare ratios from one run.
# Needs GNU time (apt-get install -y time).
set -euo pipefail
cd "$(dirname "$0")/.."
dem=${1:-bench/.work/dem4096.tif}
bin=${BIN:-${CARGO_TARGET_DIR:-target}/release/normalfit}
sizes=${SIZES:-3 9 33 63 255}
reps=${REPS:-1}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
# The best user time of $reps runs of one build at one N and weights.
user() {
  local best=
  for _ in $(seq "$reps"); do
    rm -f "$out/s.tif" "$out"/s.tif.*
    /usr/bin/time -f '%U' -o "$out/t" "$1" convert "$dem" -o "$out/s.tif" --units map --product slope \
      --border clamp -n "$2" --weights "$3" >/dev/null || { echo "$1 failed at N = $2, $3" >&2; exit 1; }
    local t
    t=$(cat "$out/t")
    best=$(python3 -c "print(min(x for x in [$t, ${best:-$t}]))")
  done
  echo "$best"
}
if [ -n "${BASELINE:-}" ]; then
  echo "| N | uniform | binomial | ratio | baseline uniform | baseline binomial | baseline ratio |"
  echo "|---|---|---|---|---|---|---|"
else
  echo "| N | uniform | binomial | ratio |"
  echo "|---|---|---|---|"
fi
for n in $sizes; do
  # `user` exits in its subshell: stop here too.
  u=$(user "$bin" "$n" uniform) || exit 1
  b=$(user "$bin" "$n" binomial) || exit 1
  row="| $n | $u | $b | $(python3 -c "print(f'{$b / $u:.2f}')") |"
  if [ -n "${BASELINE:-}" ]; then
    bu=$(user "$BASELINE" "$n" uniform) || exit 1
    bb=$(user "$BASELINE" "$n" binomial) || exit 1
    row="$row $bu | $bb | $(python3 -c "print(f'{$bb / $bu:.2f}')") |"
  fi
  echo "$row"
done
echo
echo "user CPU seconds, best of $reps; load average $(cut -d' ' -f1-3 /proc/loadavg)"
