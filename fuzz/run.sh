#!/usr/bin/env bash
# Builds the fuzz targets and runs each for SECONDS, one after the other,
# from the committed seeds (fuzz/seeds/TARGET for a target that has its
# own, else fuzz/seeds, which libFuzzer reads with its subfolders) and
# the working corpus
# (fuzz/corpus/TARGET, kept between runs, git-ignored). Prints per target:
# executions, exec/s, coverage (libFuzzer's cov: and ft: at the end),
# corpus size and findings (new files in fuzz/artifacts/TARGET).
#
#   fuzz/run.sh SECONDS [TARGET...]      default: every target
#
# Needs cargo-fuzz (`cargo install cargo-fuzz --locked`). The sanitizer
# flags cargo-fuzz passes are unstable: RUSTC_BOOTSTRAP=1 lets the stable
# toolchain take them. One job per target: the targets already use every
# core through rayon. Logs: fuzz/logs/TARGET.log.
set -euo pipefail

secs=${1:?usage: fuzz/run.sh SECONDS [TARGET...]}
shift
cd "$(dirname "$0")"
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    targets=(decode_fit tiling png_stream exr_stream geotiff_tags raw_sizes rgb_packed inverse python_entry)
fi

export RUSTC_BOOTSTRAP=1
cargo fuzz build

# One known false leak, see the file.
export LSAN_OPTIONS="suppressions=$PWD/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"

# -rss_limit_mb also caps a single allocation (libFuzzer's -malloc_limit_mb
# defaults to it), so a forged size that reaches an allocator is a finding.
# -timeout: no case of at most 2^20 texels takes seconds; one that does is a
# hang. -max_len: room for the mutator to grow inputs past the largest
# seed, small enough to keep cases fast.
fuzz_flags=(-max_total_time="$secs" -rss_limit_mb=2048 -timeout=10 -max_len=16384 -print_final_stats=1)

mkdir -p logs
summary=()
failed=0
for t in "${targets[@]}"; do
    mkdir -p "corpus/$t" "artifacts/$t"
    stamp=$(mktemp)
    log="logs/$t.log"
    echo "== $t: ${secs}s"
    status=0
    seeds=seeds
    [ -d "seeds/$t" ] && seeds="seeds/$t"
    cargo fuzz run "$t" "corpus/$t" "$seeds" -- "${fuzz_flags[@]}" >"$log" 2>&1 || status=$?

    # The last status line ("#N ... cov: C ft: F corp: U/S ... exec/s: E")
    # and the final stats, which libFuzzer prints on a clean stop.
    last=$(grep -E '^#[0-9]+' "$log" | grep 'cov:' | tail -n 1 || true)
    field() { sed -nE "s|.*$1: ([^ ]+).*|\1|p" <<<"$last"; }
    execs=$(sed -nE 's/^stat::number_of_executed_units: ([0-9]+)/\1/p' "$log" | tail -n 1)
    rate=$(sed -nE 's/^stat::average_exec_per_sec: ([0-9]+)/\1/p' "$log" | tail -n 1)
    [ -n "$execs" ] || execs=$(sed -nE 's/^#([0-9]+).*/\1/p' <<<"$last")
    [ -n "$rate" ] || rate=$(field 'exec/s')
    corpus_files=$(find "corpus/$t" -type f | wc -l)
    corpus_kb=$(du -sk --apparent-size "corpus/$t" | cut -f1)
    findings=$(find "artifacts/$t" -type f -newer "$stamp" | sort)
    rm -f "$stamp"

    line="$t: ${execs:-?} executions, ${rate:-?} exec/s, cov ${last:+$(field cov)} ft ${last:+$(field ft)}, corpus $corpus_files files ($corpus_kb KB), findings $(grep -c . <<<"$findings" || true)"
    echo "$line"
    summary+=("$line")
    if [ "$status" -ne 0 ] || [ -n "$findings" ]; then
        failed=1
        grep -E '^(SUMMARY|==[0-9]+==ERROR)|panicked at|^Test unit written' "$log" | sed 's/^/    /' || true
        for f in $findings; do echo "    finding: fuzz/$f"; done
        echo "    log: fuzz/$log (exit status $status)"
    fi
done

echo
echo "== summary (${secs}s per target)"
printf '%s\n' "${summary[@]}"
exit "$failed"
