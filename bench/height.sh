#!/usr/bin/env bash
# Times `normalfit height` against `normalfit convert` of the same height
# map (float EXR in and out both ways), in one run: each command 3 times,
# the best wall time and the highest peak RSS (/usr/bin/time), and the
# round trip's error (examples/height_error.rs). Prints a Markdown table.
#
#   bench/height.sh          # 4096² (bench/.work/h4096.png, ridged fractal noise, tiles)
#   bench/height.sh 1024     # another size
#
# Needs a Rust toolchain and GNU time (apt-get install -y time).
set -euo pipefail
cd "$(dirname "$0")/.."
size=${1:-4096}
target=${CARGO_TARGET_DIR:-target}
work=bench/.work
mkdir -p "$work"
cargo build --release --locked --bin normalfit --example heightmap --example height_error
bin=$target/release/normalfit
h=$work/h$size.png
[ -f "$h" ] || "$target/release/examples/heightmap" "$size" "$h"

# best wall time (s) and highest peak RSS (MiB) of 3 runs of "$@"
measure() {
  local best=999999 peak=0 t m
  for _ in 1 2 3; do
    /usr/bin/time -f '%e %M' -o "$work/time.txt" "$@" >/dev/null 2>"$work/stderr.txt" || { cat "$work/stderr.txt" >&2; exit 1; }
    read -r t m < "$work/time.txt"
    best=$(python3 -c "print(min($best, $t))")
    peak=$(( m > peak ? m : peak ))
  done
  echo "$best $((peak / 1024))"
}

echo "| ${size}² | wall (best of 3) | × convert | peak RSS | round trip (max, RMS of the range) |"
echo "|---|---|---|---|---|"
# Side by side with `convert` of the same heights, float EXR in and out
# both ways: the heights the default inverse finds, converted again.
"$bin" convert "$h" -o "$work/n$size.exr" -s 8
"$bin" height "$work/n$size.exr" -o "$work/heights$size.exr" -s 8
read -r tc mc < <(measure "$bin" convert "$work/heights$size.exr" -o "$work/again$size.exr" -s 8)
echo "| convert -s 8 (orthogonal, wrap), float EXR heights → float EXR | $tc s | 1 | $mc MiB | |"
row() {
  local label=$1; shift
  read -r t m < <(measure "$bin" height "$work/n$size.exr" -o "$work/back$size.exr" -s 8 "$@")
  err=$("$target/release/examples/height_error" "$h" "$work/back$size.exr")
  ratio=$(python3 -c "print(f'{$t / $tc:.2f}')")
  echo "| height -s 8 $label | $t s | $ratio | $m MiB | $err |"
}
row "(orthogonal, wrap: the default)"
"$bin" convert "$h" -o "$work/n$size.exr" -s 8 --fit vertical
row "--fit vertical" --fit vertical
"$bin" convert "$h" -o "$work/n$size.exr" -s 8 --fit vertical --border mirror
row "--fit vertical --border mirror" --fit vertical --border mirror
row "--model generic (of the vertical, mirror map)" --model generic --border mirror
"$bin" convert "$h" -o "$work/n$size.exr" -s 8 --border mirror
row "--border mirror (orthogonal)" --border mirror
