#!/usr/bin/env bash
# The whole phri-spring pipeline on the bundled SYNTHETIC examples, everything under OUT.
#   bash examples/quickstart.sh [OUT]        (run from the repository root; OUT defaults to out)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out}
mkdir -p "$OUT"

echo "== 1/3 fit-stiffness: indenter trials -> tissue stiffness map"
phri fit-stiffness examples/indenter -o "$OUT/stiffness.csv" --plots "$OUT/stiffness"

# the Harmony config with the fitted map as tissue.stiffness (a path relative to the config)
sed -E 's|^(  stiffness: )4242\.0( .*)?$|\1stiffness.csv   # N/m, fitted by phri fit-stiffness|' \
    configs/harmony_upper_arm.yaml > "$OUT/harmony_fitted.yaml"
grep -q 'stiffness: stiffness.csv' "$OUT/harmony_fitted.yaml"

echo "== 2/3 simulate: wrench log -> 21 contact forces per sample"
phri simulate "$OUT/harmony_fitted.yaml" examples/wrench_log.csv -o "$OUT/forces.csv" --baseline first:5

echo "== 3/3 compare: rigid vs compliant arm against the sensorized cuff"
phri compare "$OUT/harmony_fitted.yaml" examples/experiment/manifest.yaml -o "$OUT/compare"

echo "done: see $OUT/ (stiffness.csv, stiffness/, forces.csv, compare/report.md)"
