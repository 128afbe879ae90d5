#!/usr/bin/env bash
# Benchmark peer: a tangent-space normal map with ImageMagick 6 (HDRI build).
#
#     bench/peers/imagemagick/normals.sh IN.png OUT.png S
#
# The idiomatic fast way: whole-image operators only, no per-pixel -fx (which
# runs an interpreter per pixel and is orders of magnitude slower). The HDRI
# build (convert-im6.q16hdri, Debian package imagemagick-6.q16hdri) keeps
# negative and >1 intermediate values; the plain Q16 build clips them to
# [0, 1] and cannot hold a signed gradient.
#
#   a = -S·∂h/∂x  : -morphology Convolve Sobel:180, kernel scaled by S/8
#   b = +S·∂h/∂row: -morphology Convolve Sobel:90,  kernel scaled by S/8
#   z = (a² + b² + 1)^-½, x = a·z, y = b·z   (compose Multiply/Plus, -evaluate)
#   c = (n + 1) / 2 per channel, -combine, 8-bit RGB PNG
#
# h = value / 65535 (ImageMagick's quantum scale), -virtual-pixel tile = wrap
# borders, like normalfit's default. compose:clamp=false keeps the HDRI
# composites signed.
set -euo pipefail
in=$1 out=$2 s=$3
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
k=$(awk -v s="$s" 'BEGIN { printf "%.9g", s / 8 }')
export MAGICK_CONFIGURE_PATH=$here
exec convert-im6.q16hdri "$in" -virtual-pixel tile \
    -define convolve:scale="$k" -define compose:clamp=false \
    \( -clone 0 -morphology Convolve Sobel:180 \) \
    \( -clone 0 -morphology Convolve Sobel:90 \) -delete 0 \
    \( -clone 0,0 -compose Multiply -composite \) \
    \( -clone 1,1 -compose Multiply -composite \) \
    \( -clone 2,3 -compose Plus -composite -evaluate Add 100% -evaluate Pow -0.5 \) -delete 2,3 \
    \( -clone 0,2 -compose Multiply -composite \) \
    \( -clone 1,2 -compose Multiply -composite \) -delete 0,1 -swap 0,1 -swap 1,2 \
    -function Polynomial 0.5,0.5 -combine -depth 8 "PNG24:$out"
