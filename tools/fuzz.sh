#!/usr/bin/env bash
# The fuzzing campaign: every target of fuzz/ for RUNS executions (default 10 million) under
# libFuzzer, seeded with the shipped files (data/, fuzz/seeds/), with a 1 s timeout and a
# 2 GiB memory limit; then the corpus is minimised into fuzz/corpus/TARGET, which the stable
# test `fuzz_corpus_replays` (tests/io.rs) replays on every test run.
# Needs the nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`).
# Usage: tools/fuzz.sh [RUNS] [TARGET...]     e.g. tools/fuzz.sh 100000 json
# FUZZ_WORKERS=N splits RUNS over N processes sharing the corpus (their logs: fuzz-0.log …);
# the 2026-12-01 campaign ran `scene` with 2, the other targets with 1.
# A crash stops the run; its input is in fuzz/artifacts/TARGET/: copy it into
# fuzz/regressions/TARGET/ with the fix, so the replay test keeps it fixed.
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
runs=${1:-10000000}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(obj bpt json scene iges step cli_args)
# Release speed with debug assertions and overflow checks on, as the tests build; no
# sanitizer: the crate is safe Rust, so what the campaign hunts is panics, hangs and memory
# growth, which libFuzzer catches itself (its RSS limit) — at 2–3× the speed under ASan.
build=(-O -a -s none)
for target in "${targets[@]}"; do
  seeds=(../data)
  [ "$target" = cli_args ] && seeds=(seeds/cli_args)
  # The shipped IGES parts pass -max_len: small whole files seed the reader's entities too.
  [ "$target" = iges ] && seeds=(seeds/iges ../data)
  # STEP: small hand-made solids (a box, a cylinder with a seam) and the shipped parts.
  [ "$target" = step ] && seeds=(seeds/step ../data)
  mkdir -p "corpus/$target"
  start=$(date +%s)
  workers=${FUZZ_WORKERS:-1}
  parallel=()
  [ "$workers" -gt 1 ] && parallel=(-jobs="$workers" -workers="$workers")
  cargo +nightly fuzz run "${build[@]}" "$target" "corpus/$target" "${seeds[@]}" -- \
    -runs=$((runs / workers)) "${parallel[@]}" -timeout=1 -rss_limit_mb=2048 -max_len=8192 \
    -print_final_stats=1 2> "fuzz-$target.log"
  seconds=$(( $(date +%s) - start ))
  { grep -a -E "DONE" "fuzz-$target.log" || true; } | tail -1 | sed "s/^/$target: /"
  grep -a -E "stat::(number_of_executed_units|peak_rss_mb)" "fuzz-$target.log" | sed "s/^/$target: /"
  echo "$target: $seconds s"
  # Keep the smallest corpus with the same coverage.
  cargo +nightly fuzz cmin "${build[@]}" "$target" "corpus/$target" >/dev/null 2>&1
  echo "$target: corpus $(ls "corpus/$target" | wc -l) inputs, $(du -sh "corpus/$target" | cut -f1)"
done
