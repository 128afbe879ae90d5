#!/usr/bin/env bash
# The 4096² PNG conversion against its codec floor (issue 36, point 6), in
# one run, turn about: examples/codec_floor.rs on the 16-bit height map of
# bench/height.sh (ridged fractal noise), 8-bit RGB out. Prints a Markdown
# table (decode alone, encode alone, the two overlapped, the library's
# conversion and the command line's) and each conversion over the floor.
#
#   bench/codec_floor.sh [SIZE] [ROUNDS]     # 4096², 9 rounds
set -euo pipefail
cd "$(dirname "$0")/.."
size=${1:-4096}
rounds=${2:-9}
target=${CARGO_TARGET_DIR:-target}
work=bench/.work
mkdir -p "$work"
cargo build --release --locked --bin normalfit --example heightmap --example codec_floor
h=$work/h$size.png
[ -f "$h" ] || "$target/release/examples/heightmap" "$size" "$h"
"$target/release/examples/codec_floor" "$h" "$rounds" "$target/release/normalfit"
