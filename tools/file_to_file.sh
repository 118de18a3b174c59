#!/usr/bin/env bash
# Times `knotwork tessellate` of the teapot at 256² per patch to PLY and glb against `dd` of
# the same byte count (1 MiB blocks, fsync), alternating, with hyperfine (Debian: hyperfine).
# Usage: tools/file_to_file.sh [KNOTWORK...]   (default target/release/knotwork; several
# builds are timed side by side). Runs: RUNS (default 21); backend: BACKEND (default cpu).
set -euo pipefail
cd "$(dirname "$0")/.."
builds=("${@:-target/release/knotwork}")
runs=${RUNS:-21}
backend=${BACKEND:-cpu}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for format in ply glb; do
  out="$work/t.$format"
  "${builds[0]}" tessellate data/teapot.bpt --grid 256x256 -o "$out" --backend "$backend" >/dev/null
  bytes=$(stat -c %s "$out")
  commands=()
  for build in "${builds[@]}"; do
    commands+=("$build tessellate data/teapot.bpt --grid 256x256 -o $out --backend $backend")
  done
  commands+=("dd if=/dev/zero of=$work/dd.bin bs=1M count=$bytes iflag=count_bytes conv=fsync status=none")
  hyperfine -N -w 2 -r "$runs" --prepare "rm -f $out $work/dd.bin" "${commands[@]}" \
    --export-json "$work/$format.json" >/dev/null
  python3 - "$work/$format.json" "$format" "$bytes" <<'PY'
import json, statistics, sys
results = json.load(open(sys.argv[1]))["results"]
dd = statistics.median(results[-1]["times"])
for result in results:
    times = result["times"]
    median = statistics.median(times)
    print(f"{sys.argv[2]} ({sys.argv[3]} bytes) {result['command'].split()[0]}: median {median * 1e3:.0f} ms "
          f"({min(times) * 1e3:.0f}-{max(times) * 1e3:.0f}), user {result['user'] * 1e3:.0f} ms, "
          f"system {result['system'] * 1e3:.0f} ms, {median / dd:.2f}x dd")
PY
done
