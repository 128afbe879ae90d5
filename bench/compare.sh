#!/usr/bin/env bash
# Times normalfit against the tools users could pick instead, on the same
# height maps, and prints a Markdown table (see bench/README.md).
#
#     bench/compare.sh          # install peers, make inputs, time, print the table
#     bench/compare.sh --big    # only normalfit on a 32768² map (≈0.9 GB input, ≈8 GiB RAM)
#
# Runs from any directory (it finds the repository from its own path).
# Progress goes to standard error, the table to standard output (and to
# bench/.work/results.md, or big.md for --big).
set -euo pipefail
# Numbers with a decimal point and character-wise string lengths, whatever the user's locale.
if locale -a 2>/dev/null | grep -qix 'c.utf-\{0,1\}8'; then export LC_ALL=C.UTF-8; else export LC_ALL=C; fi

# ---------------------------------------------------------------- settings --

# Height gain for every tool: S = RELIEF × width texels for the [0, 1] height
# range (normalfit's --relief), so the maps look alike at both sizes and are
# neither flat nor saturated. Peers get the same S in their own units.
RELIEF=${RELIEF:-0.03}
# The normalfit command under test is "$NORMALFIT convert IN -o OUT.png" plus
# these options: add the options of later versions here.
NORMALFIT_OPTS=${NORMALFIT_OPTS:-"--bits 8 --relief $RELIEF"}
SIZES=(1024 4096)
BIG_SIZE=32768
RUNS=3                # each tool and size: best (lowest wall time) of RUNS
RUN_TIMEOUT=1200      # seconds before one run counts as failed
# Pinned peers (Python pins are in bench/peers/requirements.txt).
NORMAL_HEIGHTS_VERSION=0.1.2
APT_PEERS=(imagemagick imagemagick-6.q16hdri gmic gegl libnvtt-bin)

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BENCH=$ROOT/bench
PEERS=$BENCH/.peers           # installed peers (git-ignored)
WORK=${BENCH_WORK:-$BENCH/.work}   # inputs, outputs, logs (git-ignored)
cd "$ROOT"

BIG=0
for arg in "$@"; do
    case $arg in
        --big) BIG=1 ;;
        -h | --help) sed -n '2,10p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "compare.sh: unknown argument '$arg' (try --help)" >&2; exit 2 ;;
    esac
done

log() { printf '[compare] %s\n' "$*" >&2; }
# One line, safe inside a Markdown table cell.
cell() {
    local s
    s=$(tr '\n' ' ' <<<"$*" | sed 's/|/\\|/g; s/  */ /g; s/^ //; s/ $//')
    (( ${#s} > 160 )) && s="${s:0:159}…"
    printf '%s\n' "$s"
}
mkdir -p "$WORK/out" "$WORK/log" "$PEERS"

# ----------------------------------------------------------------- install --

declare -A UNAVAILABLE=()   # tool or package -> why it cannot run

as_root() {
    if [[ $(id -u) -eq 0 ]]; then "$@"
    elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then sudo "$@"
    else return 99
    fi
}

APT_UPDATED=0
apt_installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q 'install ok installed'; }
# apt_ensure PKG: installs PKG unless present; on failure records why.
apt_ensure() {
    local pkg=$1 rc=0
    apt_installed "$pkg" && return 0
    if ! command -v apt-get >/dev/null; then UNAVAILABLE[$pkg]="no apt-get"; return 1; fi
    if [[ $APT_UPDATED -eq 0 ]]; then
        log "apt-get update"
        as_root apt-get update >"$WORK/log/apt-update.log" 2>&1 || rc=$?
        if [[ $rc -eq 99 ]]; then UNAVAILABLE[$pkg]="apt needs root"; return 1; fi
        APT_UPDATED=1
    fi
    log "apt-get install $pkg"
    rc=0
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "$pkg" \
        >"$WORK/log/apt-$pkg.log" 2>&1 || rc=$?
    if [[ $rc -ne 0 ]]; then
        UNAVAILABLE[$pkg]="apt-get install $pkg: $(grep -E '^E:' "$WORK/log/apt-$pkg.log" | head -1 || true)"
        [[ $rc -eq 99 ]] && UNAVAILABLE[$pkg]="apt needs root"
        return 1
    fi
}

if [[ ! -x /usr/bin/time ]]; then
    apt_ensure time || { echo "compare.sh: /usr/bin/time is needed: ${UNAVAILABLE[time]}" >&2; exit 1; }
fi

install_peers() {
    local pkg
    for pkg in "${APT_PEERS[@]}"; do apt_ensure "$pkg" || log "not available: ${UNAVAILABLE[$pkg]}"; done

    # Python peers: a venv in bench/.peers (pip --target as a fallback where
    # the venv module is missing), pinned by requirements.txt.
    local req=$BENCH/peers/requirements.txt
    PY=$PEERS/venv/bin/python
    PYTHONPATH_PEERS=
    local check_pins='import sys, importlib.metadata as md
for line in open(sys.argv[1]):
    line = line.split("#")[0].strip()
    if line:
        name, version = line.split("==")
        if md.version(name) != version: sys.exit(1)'
    if [[ -x $PY ]] && "$PY" -c "$check_pins" "$req" 2>/dev/null; then
        :
    elif python3 -m venv "$PEERS/venv" >"$WORK/log/venv.log" 2>&1; then
        log "pip install -r bench/peers/requirements.txt (venv)"
        "$PY" -m pip install -q -r "$req" >"$WORK/log/pip.log" 2>&1 \
            || UNAVAILABLE[python]="pip install: $(grep -m1 -E 'ERROR' "$WORK/log/pip.log" || tail -1 "$WORK/log/pip.log")"
    else
        log "python3 -m venv failed; pip install --target bench/.peers/pylib"
        PY=python3
        PYTHONPATH_PEERS=$PEERS/pylib
        if ! PYTHONPATH=$PYTHONPATH_PEERS python3 -c "$check_pins" "$req" 2>/dev/null; then
            python3 -m pip install -q --target "$PEERS/pylib" -r "$req" >"$WORK/log/pip.log" 2>&1 \
                || UNAVAILABLE[python]="pip install: $(grep -m1 -E 'ERROR' "$WORK/log/pip.log" || tail -1 "$WORK/log/pip.log")"
        fi
    fi

    # normal-heights ships a CLI (src/main.rs, binary "normal-heights").
    NORMAL_HEIGHTS=$PEERS/bin/normal-heights
    if ! { [[ -x $NORMAL_HEIGHTS ]] && "$NORMAL_HEIGHTS" --version 2>/dev/null | grep -qF "$NORMAL_HEIGHTS_VERSION"; }; then
        log "cargo install normal-heights --version $NORMAL_HEIGHTS_VERSION --locked"
        cargo install normal-heights --version "$NORMAL_HEIGHTS_VERSION" --locked --root "$PEERS" \
            >"$WORK/log/cargo-normal-heights.log" 2>&1 \
            || UNAVAILABLE[normal-heights]="cargo install: $(grep -m1 '^error' "$WORK/log/cargo-normal-heights.log" || true)"
    fi

    # imageproc: our own small program, its own workspace and target dir.
    IMAGEPROC_BIN=$PEERS/target/release/imageproc-normals
    log "cargo build bench/peers/imageproc"
    cargo build --release --locked --manifest-path "$BENCH/peers/imageproc/Cargo.toml" \
        --target-dir "$PEERS/target" >"$WORK/log/cargo-imageproc.log" 2>&1 \
        || UNAVAILABLE[imageproc]="cargo build: $(grep -m1 '^error' "$WORK/log/cargo-imageproc.log" || true)"
}

# ------------------------------------------------------ normalfit + inputs --

build_normalfit() {
    log "cargo build --release (normalfit)"
    cargo build --release >"$WORK/log/cargo-normalfit.log" 2>&1 \
        || { tail -20 "$WORK/log/cargo-normalfit.log" >&2; echo "compare.sh: normalfit does not build" >&2; exit 1; }
    local target
    target=$(cargo metadata --format-version 1 --no-deps 2>/dev/null \
        | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
    NORMALFIT=$target/release/normalfit
    TARGET_DIR=$target
    log "cargo build --release --example heightmap"
    cargo build --release --example heightmap >>"$WORK/log/cargo-normalfit.log" 2>&1
}

# make_input SIZE: WORK/hSIZE.png, the same every run (the example is deterministic).
make_input() {
    local size=$1 out=$WORK/h$1.png
    log "cargo run --release --example heightmap -- $size $out"
    cargo run --release --example heightmap -- "$size" "$out" >>"$WORK/log/heightmap.log" 2>&1
}

# ------------------------------------------------------------------- peers --
# Each peer: peer_<id> sets CMD (argv) for IN, OUT, S, SIZE; TOOLS lists
# id | name | what it computes | output extension.

TOOLS=(
    "normalfit|normalfit|LSQ plane fit 3×3, orthogonal (default), wrap|png"
    "numpy|numpy np.gradient|central differences, one-sided at edges|png"
    "scipy|SciPy ndimage.sobel|Sobel 3×3, wrap|png"
    "opencv|OpenCV cv2.Sobel|Sobel 3×3, mirror border|png"
    "imageproc|imageproc (Rust)|Sobel 3×3 on 16-bit, clamp|png"
    "normal_heights|normal-heights (Rust CLI)|Sobel 3×3 on 8-bit luma, clamp|png"
    "imagemagick|ImageMagick (HDRI)|Sobel 3×3 via -morphology Convolve, tile|png"
    "gmic|G'MIC|Sobel 3×3 via gradient xy,2, clamp|png"
    "gegl|GEGL gegl:normal-map|central differences, tileable|png"
    "nvcompress|nvcompress -tonormal|Sobel 3/5/7/9 blend on 8-bit, fixed gain|dds"
)

py_cmd() {
    if [[ -n $PYTHONPATH_PEERS ]]; then CMD=(env "PYTHONPATH=$PYTHONPATH_PEERS" "$PY" "$@"); else CMD=("$PY" "$@"); fi
}
peer_normalfit()      { read -ra opts <<<"$NORMALFIT_OPTS"; CMD=("$NORMALFIT" convert "$IN" -o "$OUT" "${opts[@]}"); }
peer_numpy()          { py_cmd "$BENCH/peers/np_gradient.py" "$IN" "$OUT" "$S"; }
peer_scipy()          { py_cmd "$BENCH/peers/scipy_sobel.py" "$IN" "$OUT" "$S"; }
peer_opencv()         { py_cmd "$BENCH/peers/opencv_sobel.py" "$IN" "$OUT" "$S"; }
peer_imageproc()      { CMD=("$IMAGEPROC_BIN" "$IN" "$OUT" "$S"); }
# normal-heights: n ∝ (−Sobel_x, +Sobel_y, 1/strength) on h = 8-bit value / 255,
# and a Sobel sum is 8 × the slope, so strength = S / 8.
peer_normal_heights() { CMD=("$NORMAL_HEIGHTS" -s "$(awk -v s="$S" 'BEGIN{printf "%.9g", s/8}')" "$IN" "$OUT"); }
peer_imagemagick()    { CMD=("$BENCH/peers/imagemagick/normals.sh" "$IN" "$OUT" "$S"); }
# G'MIC reads 16-bit PNG values as 0…65535: scale by S/8/65535, Sobel (scheme 2),
# negate x, append z = 1, normalise (orientation), encode to 0…255.
peer_gmic() {
    CMD=(gmic -v -1 -input "$IN" -mul "$(awk -v s="$S" 'BEGIN{printf "%.9g", s/8/65535}')"
        -gradient xy,2 -mul[0] -1 +fill[-1] 1 -append c -orientation
        -mul 127.5 -add 127.5 -round -cut 0,255 -output "$OUT")
}
# gegl:normal-map: n ∝ (scale·(l − r)/2, scale·(t − b)/2, 1), so scale = S;
# flip-y for green up; 8-bit RGB without alpha.
peer_gegl() {
    CMD=(gegl "$IN" -- gegl:normal-map "scale=$S" flip-y=true tileable=true
        gegl:convert-format "format=R'G'B' u8" gegl:png-save "path=$OUT" bitdepth=8)
}
# nvtt 2.0 has no gain or convention option on the command line; -rgb -nomips
# writes an uncompressed A8R8G8B8 DDS with the full-size level only.
peer_nvcompress()     { CMD=(nvcompress -tonormal -repeat -rgb -nomips -nocuda "$IN" "$OUT"); }

# Why a tool cannot run here, or nothing.
why_unavailable() {
    case $1 in
        numpy | scipy | opencv) echo "${UNAVAILABLE[python]:-}" ;;
        imageproc) echo "${UNAVAILABLE[imageproc]:-}" ;;
        normal_heights) echo "${UNAVAILABLE[normal-heights]:-}" ;;
        imagemagick)
            echo "${UNAVAILABLE[imagemagick-6.q16hdri]:-}"
            [[ -n ${UNAVAILABLE[imagemagick-6.q16hdri]:-} ]] || command -v convert-im6.q16hdri >/dev/null || echo "no convert-im6.q16hdri" ;;
        gmic) echo "${UNAVAILABLE[gmic]:-}"; [[ -n ${UNAVAILABLE[gmic]:-} ]] || command -v gmic >/dev/null || echo "no gmic" ;;
        gegl) echo "${UNAVAILABLE[gegl]:-}"; [[ -n ${UNAVAILABLE[gegl]:-} ]] || command -v gegl >/dev/null || echo "no gegl" ;;
        nvcompress)
            echo "${UNAVAILABLE[libnvtt-bin]:-}"
            [[ -n ${UNAVAILABLE[libnvtt-bin]:-} ]] || command -v nvcompress >/dev/null || echo "no nvcompress" ;;
    esac
}

deb_version() { dpkg-query -W -f='${Version}' "$1" 2>/dev/null | sed 's/^[0-9]*://; s/[-+~].*//'; }
tool_version() {
    local v=
    case $1 in
        normalfit) v="$("$NORMALFIT" --version | awk '{print $NF}') ($(git rev-parse --short HEAD 2>/dev/null || echo '?'))" ;;
        numpy) v=$("${CMD_ENV[@]}" "$PY" -c 'import numpy; print(numpy.__version__)') ;;
        scipy) v=$("${CMD_ENV[@]}" "$PY" -c 'import scipy; print(scipy.__version__)') ;;
        opencv) v=$("${CMD_ENV[@]}" "$PY" -c 'import cv2; print(cv2.__version__)') ;;
        imageproc) v=$(awk '/^name = "imageproc"$/ { getline; gsub(/"/, "", $3); print $3 }' "$BENCH/peers/imageproc/Cargo.lock") ;;
        normal_heights) v=$("$NORMAL_HEIGHTS" --version | awk '{print $NF}') ;;
        imagemagick) v=$(convert-im6.q16hdri -version | awk 'NR == 1 {print $3}') ;;
        gmic) v=$(deb_version gmic) ;;
        gegl) v=$(deb_version gegl) ;;
        nvcompress) v=$(deb_version libnvtt-bin) ;;
    esac
    echo "${v:-?}"
}

# The check cell from "SIZE<tab>NOTE" lines: each failure or wrong output
# once, with the sizes it happened at, then the largest size's check if it
# passed.
summarize_checks() {
    awk -F'\t' -v large="$1" '
        NF < 2 { next }
        $2 ~ /^(failed|WRONG)/ {
            if (!($2 in at)) order[++n] = $2
            at[$2] = at[$2] (at[$2] == "" ? "" : ", ") $1 "²"
            next
        }
        $1 == large { ok = $2 }
        END {
            for (i = 1; i <= n; i++) out = out (out == "" ? "" : "; ") at[order[i]] ": " order[i]
            if (ok != "") out = out (out == "" ? "" : "; ") ok
            print out
        }'
}

# ------------------------------------------------------------------ timing --

# The arguments as one line a shell would read back the same.
shell_words() {
    local a out=()
    for a in "$@"; do
        if [[ $a =~ ^[A-Za-z0-9_./=:,+%@^-]+$ ]]; then out+=("$a")
        elif [[ $a != *[\"\$\`\\!]* ]]; then out+=("\"$a\"")
        else out+=("'${a//\'/\'\\\'\'}'")
        fi
    done
    echo "${out[*]}"
}

now_ns() { date +%s%N; }
fmt_s()   { awk -v ns="$1" 'BEGIN { printf "%.3f", ns / 1e9 }'; }
fmt_mib() { awk -v k="$1" 'BEGIN { printf "%.0f MiB", k / 1024 }'; }
fmt_size() { awk -v b="$1" 'BEGIN { if (b >= 1048576) printf "%.1f MiB", b / 1048576; else printf "%.0f KiB", b / 1024 }'; }
ratio()   { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", a / b }'; }

# time_tool ID SIZE RUNS: runs the tool; sets BEST_NS, PEAK_KB, FAIL, OUT, CMD.
time_tool() {
    local id=$1 size=$2 runs=$3 ext=$4 i t0 t1 rc tf errf
    IN=$WORK/h$size.png
    OUT=$WORK/out/$id-$size.$ext
    S=$(awk -v r="$RELIEF" -v w="$size" 'BEGIN { printf "%.9g", r * w }')
    SIZE=$size
    "peer_$id"
    BEST_NS= PEAK_KB=0 FAIL=
    tf=$WORK/log/$id-$size.time errf=$WORK/log/$id-$size.err
    for ((i = 1; i <= runs; i++)); do
        rm -f "$OUT"
        rc=0
        t0=$(now_ns)
        /usr/bin/time -f '%e %M' -o "$tf" timeout "$RUN_TIMEOUT" "${CMD[@]}" >"$errf.out" 2>"$errf" || rc=$?
        t1=$(now_ns)
        if [[ $rc -ne 0 ]]; then
            if [[ $rc -eq 124 ]]; then FAIL="failed: timed out after ${RUN_TIMEOUT} s"
            else FAIL="failed (exit $rc): $(sed 's/\x1b\[[0-9;]*m//g' "$errf" | grep -v '^\s*$' | tail -1 || true)"
            fi
            return 0
        fi
        local kb
        kb=$(awk 'END { print $2 }' "$tf")
        (( kb > PEAK_KB )) && PEAK_KB=$kb
        if [[ -z $BEST_NS ]] || (( t1 - t0 < BEST_NS )); then BEST_NS=$((t1 - t0)); fi
        log "  $id $size² run $i: $(fmt_s $((t1 - t0))) s (time: $(cat "$tf"))"
    done
}

# check_output FILE SIZE [REF]: one line from bench/peers/check.py; status 1 if wrong.
check_output() {
    local py=python3
    [[ -z ${UNAVAILABLE[python]:-} && -n ${PY:-} ]] && py=$PY
    "${CMD_ENV[@]}" "$py" "$BENCH/peers/check.py" "$@"
}

# Machine and date, taken when the run starts.
machine_header() {
    local cpu mem os rustc
    cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//' || echo '?')
    mem=$(awk '/MemTotal/ { printf "%.1f GiB", $2 / 1048576 }' /proc/meminfo)
    os=$(. /etc/os-release 2>/dev/null && echo "$PRETTY_NAME" || uname -sr)
    rustc=$(rustc --version | awk '{print $2}')
    echo "Date: $(date -u '+%Y-%m-%d %H:%M UTC'). Machine: $cpu, nproc $(nproc), $mem RAM, $os, rustc $rustc; load average at start $(cut -d' ' -f1-3 /proc/loadavg)."
}

# --------------------------------------------------------------- --big ----

run_big() {
    local header; header=$(machine_header)
    build_normalfit
    local big=$WORK/h$BIG_SIZE.png stamp=$WORK/h$BIG_SIZE.stamp want avail_gb
    want="$(sha256sum examples/heightmap.rs | cut -c1-16) $BIG_SIZE"
    if [[ -f $big && -f $stamp && $(cat "$stamp") == "$want" ]]; then
        log "reusing $big (same generator)"
    else
        avail_gb=$(df -P --block-size=1G "$WORK" | awk 'NR == 2 { print $4 }')
        if (( avail_gb < 4 )); then
            echo "compare.sh --big: needs about 4 GB free in $WORK (input ≈0.9 GB, output ≈0.8 GB, slack); $avail_gb GB free" >&2
            exit 1
        fi
        rm -f "$big" "$stamp"
        make_input "$BIG_SIZE"
        echo "$want" >"$stamp"
    fi
    make_input 4096
    local out4=$WORK/out/normalfit-4096.png ns4 kb4 ns32 kb32 bytes32 note
    time_tool normalfit 4096 "$RUNS" png
    [[ -z $FAIL ]] || { echo "compare.sh --big: normalfit at 4096²: $FAIL" >&2; exit 1; }
    ns4=$BEST_NS kb4=$PEAK_KB
    local bytes4; bytes4=$(stat -c %s "$out4")
    log "normalfit on ${BIG_SIZE}² (one run)"
    time_tool normalfit "$BIG_SIZE" 1 png
    if [[ -n $FAIL ]]; then
        ns32= kb32= bytes32= note=$FAIL
    else
        ns32=$BEST_NS kb32=$PEAK_KB bytes32=$(stat -c %s "$OUT")
        note=$(python3 "$BENCH/peers/check.py" --size-only "$OUT" "$BIG_SIZE" "$BIG_SIZE" || true)
        rm -f "$OUT"   # ≈0.8 GB; the input is kept for the next --big run
    fi
    {
        echo "## normalfit on a ${BIG_SIZE}² height map"
        echo
        echo "$header"
        echo "Inputs: \`cargo run --release --example heightmap -- SIZE\` (16-bit gray PNG; ${BIG_SIZE}²: $(fmt_size "$(stat -c %s "$big")")). Command: \`normalfit convert IN -o OUT.png $NORMALFIT_OPTS\` (S = $RELIEF × width). 4096²: best of $RUNS runs; ${BIG_SIZE}²: one run. Peak RSS from \`/usr/bin/time -f '%e %M'\`."
        echo
        echo "| input | wall time | peak RSS | ns per texel | per texel vs 4096² | output size | check |"
        echo "|---|---:|---:|---:|---:|---:|---|"
        local t4 t32
        t4=$(awk -v ns="$ns4" -v n=$((4096 * 4096)) 'BEGIN { printf "%.1f", ns / n }')
        echo "| 4096² | $(fmt_s "$ns4") s | $(fmt_mib "$kb4") | $t4 | 1.00 | $(fmt_size "$bytes4") | |"
        if [[ -n $ns32 ]]; then
            t32=$(awk -v ns="$ns32" -v n=$((BIG_SIZE * BIG_SIZE)) 'BEGIN { printf "%.1f", ns / n }')
            echo "| ${BIG_SIZE}² | $(fmt_s "$ns32") s | $(fmt_mib "$kb32") | $t32 | $(ratio "$t32" "$t4") | $(fmt_size "$bytes32") | $(cell "$note") |"
        else
            echo "| ${BIG_SIZE}² | — | — | — | — | — | $(cell "$note") |"
        fi
    } | tee "$WORK/big.md"
}

# ------------------------------------------------------------------- main --

CMD_ENV=(env)
if [[ $BIG -eq 1 ]]; then
    run_big
    exit 0
fi

HEADER=$(machine_header)
install_peers
[[ -n $PYTHONPATH_PEERS ]] && CMD_ENV=(env "PYTHONPATH=$PYTHONPATH_PEERS")
build_normalfit
for size in "${SIZES[@]}"; do make_input "$size"; done

declare -A T M SZ CHK VER
ROWS=()
for entry in "${TOOLS[@]}"; do
    IFS='|' read -r id name computes ext <<<"$entry"
    ROWS+=("$id")
    why=$(why_unavailable "$id" | grep -v '^$' | head -1 || true)
    if [[ -n $why ]]; then
        CHK[$id]="not available ($why)"
        log "$name: not available ($why)"
        continue
    fi
    VER[$id]=$(tool_version "$id" 2>/dev/null || echo '?')
    for size in "${SIZES[@]}"; do
        log "$name at ${size}²"
        time_tool "$id" "$size" "$RUNS" "$ext"
        if [[ -n $FAIL ]]; then
            T[$id,$size]=failed
            CHK[$id]+="$size"$'\t'"$FAIL"$'\n'
            log "  $FAIL"
            continue
        fi
        T[$id,$size]=$BEST_NS
        M[$id,$size]=$PEAK_KB
        SZ[$id,$size]=$(stat -c %s "$OUT")
        ref=$WORK/out/normalfit-$size.png
        if [[ $id == normalfit ]]; then
            note=$(check_output "$OUT" "$size" "$size") || true
        else
            note=$(check_output "$OUT" "$size" "$size" "$ref") || true
        fi
        CHK[$id]+="$size"$'\t'"$note"$'\n'
        [[ $note == WRONG* ]] && log "  $note"
    done
    shell_words "${CMD[@]}" >"$WORK/log/$id.cmd"   # the last command, for the listing
done

small=${SIZES[0]} large=${SIZES[-1]}

# normalfit's output size against `image`'s default PNG settings on the same
# pixels: its large output re-encoded by the imageproc peer's --reencode.
SIZE_LINE=
nf_out=$WORK/out/normalfit-$large.png
if [[ -z ${UNAVAILABLE[imageproc]:-} && -f $nf_out && ${T[normalfit,$large]:-failed} != failed ]]; then
    reencoded=$WORK/out/normalfit-$large-image-default.png
    log "re-encoding normalfit's ${large}² output with image's default PNG settings"
    if "$IMAGEPROC_BIN" --reencode "$nf_out" "$reencoded" 2>"$WORK/log/reencode.err"; then
        nf_bytes=$(stat -c %s "$nf_out") default_bytes=$(stat -c %s "$reencoded")
        SIZE_LINE="Output size: normalfit's ${large}² PNG is $(fmt_size "$nf_bytes"); the same pixels written with \`image\`'s default PNG settings (\`imageproc-normals --reencode\`, \`DynamicImage::save\`) take $(fmt_size "$default_bytes"): normalfit's is $(ratio "$nf_bytes" "$default_bytes")× that."
        rm -f "$reencoded"
    else
        SIZE_LINE="Output size: re-encoding normalfit's ${large}² PNG with \`image\` failed: $(head -c 200 "$WORK/log/reencode.err")"
    fi
fi

{
    echo "## normalfit and its peers"
    echo
    echo "$HEADER"
    echo "Inputs: \`cargo run --release --example heightmap -- SIZE OUT.png\` (ridged fractal noise, 16-bit gray PNG; ${small}²: $(fmt_size "$(stat -c %s "$WORK/h$small.png")"), ${large}²: $(fmt_size "$(stat -c %s "$WORK/h$large.png")")). Gain S = $RELIEF × width for every tool that takes one. Output: 8-bit RGB, green up, unless noted."
    echo "Wall time: best of $RUNS runs; peak RSS: highest of the $RUNS, from \`/usr/bin/time -f '%e %M'\`; ratio: tool's time ÷ normalfit's; check: the ${large}² output against normalfit's (Δ = mean angle between the normals, tilt = the tool's gain relative to normalfit's)."
    echo
    echo "| tool | version | computes | ${small}² time | ${large}² time | ${large}² peak RSS | time ÷ normalfit ${small}² / ${large}² | ${large}² output | check |"
    echo "|---|---|---|---:|---:|---:|---:|---:|---|"
    for entry in "${TOOLS[@]}"; do
        IFS='|' read -r id name computes ext <<<"$entry"
        if [[ ${CHK[$id]:-} == "not available"* ]]; then
            echo "| $name | — | $(cell "$computes") | not available | | | | | $(cell "${CHK[$id]}") |"
            continue
        fi
        t_small=${T[$id,$small]:-failed} t_large=${T[$id,$large]:-failed}
        r_small=— r_large=—
        [[ $t_small != failed && ${T[normalfit,$small]:-failed} != failed ]] && r_small=$(ratio "$t_small" "${T[normalfit,$small]}")
        [[ $t_large != failed && ${T[normalfit,$large]:-failed} != failed ]] && r_large=$(ratio "$t_large" "${T[normalfit,$large]}")
        [[ $t_small != failed ]] && t_small="$(fmt_s "$t_small") s"
        [[ $t_large != failed ]] && t_large="$(fmt_s "$t_large") s"
        rss=— size=—
        [[ -n ${M[$id,$large]:-} ]] && rss=$(fmt_mib "${M[$id,$large]}")
        [[ -n ${SZ[$id,$large]:-} ]] && size="$(fmt_size "${SZ[$id,$large]}")"
        [[ $ext != png && $size != — ]] && size="$size (${ext^^})"
        echo "| $name | ${VER[$id]} | $(cell "$computes") | $t_small | $t_large | $rss | $r_small / $r_large | $size | $(cell "$(summarize_checks "$large" <<<"${CHK[$id]:-}")") |"
    done
    echo
    if [[ -n $SIZE_LINE ]]; then
        echo "$SIZE_LINE"
        echo
    fi
    echo "Commands (${large}²; paths relative to \`bench/.work\`, the repository and cargo's target directory):"
    echo
    echo '```'
    for id in "${ROWS[@]}"; do
        [[ -f $WORK/log/$id.cmd ]] && sed "s|$WORK/||g; s|$TARGET_DIR/|target/|g; s|$ROOT/||g" "$WORK/log/$id.cmd"
    done
    echo '```'
} | tee "$WORK/results.md"
