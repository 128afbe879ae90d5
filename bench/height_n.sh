#!/usr/bin/env bash
# `normalfit height`'s time and memory against the patch size N (issue 32,
# point 4), as a user calls it: each normal map made by `normalfit convert`
# with the options the row names, then `normalfit height` of it with the
# same. Prints a Markdown table: user CPU time and peak RSS (GNU time), one run
# each; given an older build, it runs that one too, on the same files in
# the same run, and prints the ratio of the times. Times are user CPU
# seconds (GNU time's %U: fair beside other work on a shared machine).
#
#   bench/height_n.sh                     # this build only
#   bench/height_n.sh /tmp/nf-before      # and an older binary beside it
#   bench/height_n.sh --clamp [BEFORE]    # the clamp sweep (below) instead
#   bench/height_n.sh --shapes [BEFORE]   # issue 32's shapes (below) instead
#   TIMEOUT=60 bench/height_n.sh …        # seconds a run may take (default 120)
#
# Maps: ridged fractal noise (examples/heightmap.rs) of 64², 512² and
# 1024²; a flat map of 1 × 5000 (a PGM of zeros). The clamp sweep: 512²,
# 1024², 2048 × 256 and 2048², N = 3, 5, 63, 255 and 1023, clamp with
# both fits and wrap (orthogonal) for reference. The shapes sweep: 256²,
# 1024², the strips 1030 × 3, 2 × 1100 and 3 × 20000, and 2048 × 256, at
# N = 3, 5, 63, 255 and 1023, every border with both fits; and a 3 × 20000
# map made at N = 3 inverted with N = 63 (a map not made at the N given,
# orthogonal). Needs a Rust toolchain
# and GNU time (apt-get install -y time).
set -euo pipefail
cd "$(dirname "$0")/.."
sweep=
if [ "${1:-}" = --clamp ] || [ "${1:-}" = --shapes ]; then
  sweep=${1#--}
  shift
fi
before=${1:-}
timeout=${TIMEOUT:-120}
target=${CARGO_TARGET_DIR:-target}
work=bench/.work/height_n
mkdir -p "$work"
cargo build --release --locked --bin normalfit --example heightmap
bin=$target/release/normalfit
for size in 64 256 512 1024 2048 2048x256 1030x3 2x1100 3x20000; do
  [ -f "$work/h$size.png" ] || "$target/release/examples/heightmap" "$size" "$work/h$size.png" >/dev/null
done
# A flat map one texel wide: a binary PGM of zeros.
{ printf 'P5\n1 5000\n255\n'; head -c 5000 /dev/zero; } > "$work/flat1x5000.pgm"

# "user-seconds peak-MiB" of one run of "$@", or ">T -" past the timeout
# (T in wall seconds), or "refused -" for the inverse's refusal by its
# estimate of time (`src/height/cost.rs`).
measure() {
  if /usr/bin/time -f '%U %M' -o "$work/time.txt" timeout "$timeout" "$@" >/dev/null 2>"$work/stderr.txt"; then
    read -r t m < "$work/time.txt"
    echo "$t $((m / 1024))"
  elif grep -q 'Command exited with non-zero status 124' "$work/time.txt"; then
    echo ">$timeout -"
  elif grep -q 'solved for maps with a side of at most\|operations, past the limit of\|operations, past their limit of' "$work/stderr.txt"; then
    echo "refused -"
  else
    echo "failed -"
    cat "$work/stderr.txt" >&2
  fi
}

if [ -n "$before" ]; then
  echo "| map | N | options | user before | user after | before / after | RSS before | RSS after |"
  echo "|---|---|---|---|---|---|---|---|"
else
  echo "| map | N | options | user | peak RSS |"
  echo "|---|---|---|---|---|"
fi
# row MAP N OPTIONS…: convert, then height, with -s 8 -n N and the options.
row() {
  local map=$1 n=$2; shift 2
  local label=${*:-default (orthogonal, wrap)}
  "$bin" convert "$work/$map" -o "$work/n.exr" -s 8 -n "$n" "$@" -q
  read -r ta ma < <(measure "$bin" height "$work/n.exr" -o "$work/back.exr" -s 8 -n "$n" "$@" -q)
  if [ -n "$before" ]; then
    read -r tb mb < <(measure "$before" height "$work/n.exr" -o "$work/back_before.exr" -s 8 -n "$n" "$@" -q)
    ratio=$(python3 -c "
a, b = '$ta', '$tb'
print('' if '-' in a + b or 'f' in a + b else f'{(float(b.lstrip(\">\")) / max(float(a), 0.01)):.0f}' + ('+' if b.startswith('>') else ''))")
    echo "| ${map%.*} | $n | $label | $tb s | $ta s | $ratio | $mb MiB | $ma MiB |"
  else
    echo "| ${map%.*} | $n | $label | $ta s | $ma MiB |"
  fi
}
if [ "$sweep" = shapes ]; then
  for map in h256.png h1024.png h1030x3.png h2x1100.png h3x20000.png h2048x256.png; do
    for n in 3 5 63 255 1023; do
      for border in wrap clamp mirror; do
        row "$map" "$n" --border "$border"
        row "$map" "$n" --border "$border" --fit vertical
      done
    done
  done
  # A map made at N = 3, inverted with N = 63: not the fit's own map.
  "$bin" convert "$work/h3x20000.png" -o "$work/n.exr" -s 8 -n 3 -q
  read -r t m < <(measure "$bin" height "$work/n.exr" -o "$work/back.exr" -s 8 -n 63 -q)
  echo "| h3x20000 made at N = 3 | 63 | default (orthogonal, wrap) | $t s | $m MiB |"
  exit 0
fi
if [ "$sweep" = clamp ]; then
  for map in h512.png h1024.png h2048x256.png h2048.png; do
    for n in 3 5 63 255 1023; do
      row "$map" "$n" --border clamp
      row "$map" "$n" --border clamp --fit vertical
      row "$map" "$n" --border wrap
    done
  done
  exit 0
fi
for map in h64.png h512.png; do
  for n in 3 63 255 1023; do
    row "$map" "$n"
    row "$map" "$n" --fit vertical
    row "$map" "$n" --border clamp
  done
done
for n in 3 63 255 1023; do
  row flat1x5000.pgm "$n"
  row flat1x5000.pgm "$n" --border clamp
done
for n in 3 255; do
  row h1024.png "$n"
done
