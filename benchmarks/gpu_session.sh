#!/usr/bin/env bash
# Every GPU figure docs/performance.md asks for, in one command on a lent GPU machine
# (a device session has 15 minutes in all: this takes about 6-8 on 16 cores + one H200).
#
# On the development machine, first: bash ../shared/gpu/prepare.sh   (builds .gpu/)
# On the GPU machine, from the repository root (the device tool: carry [".gpu"]):
#     bash benchmarks/gpu_session.sh "$OUT"
# It writes, under OUT:
#   gpu_e2e.json + gpu_e2e.txt   the default job end to end (--workers auto with render
#                                helpers, --workers 3 without, max_rate 1000, threads)
#   event_helpers.txt            the event camera alone, 0 vs 4 render helpers (A/B)
#   if_gpu/summary.{npz,json}    image-formation record for the renderer-parity check; on a
#                                CPU machine, record the same commit with llvmpipe and run
#                                bench_image_formation.py compare LLVM_DIR OUT/if_gpu
set -euo pipefail
OUT=${1:?usage: gpu_session.sh OUTDIR}
mkdir -p "$OUT"
if [ -f .gpu/setup.sh ]; then
    # shellcheck disable=SC1091
    source .gpu/setup.sh
fi
export PYTHONPATH=src:benchmarks
PY=${PYTHON:-python3}
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$OUT/gpu.txt" 2>&1 || true
nproc >> "$OUT/gpu.txt"
echo "== gpu_e2e" | tee "$OUT/gpu_e2e.txt"
"$PY" benchmarks/gpu_e2e.py "$OUT" 2>&1 | tee -a "$OUT/gpu_e2e.txt"
echo "== event camera alone, 0 vs 4 render helpers" | tee "$OUT/event_helpers.txt"
"$PY" benchmarks/bench_event_stream.py --ab-helpers 4 --repeat 3 --workdir "$OUT/tmp" 2>&1 \
    | tee -a "$OUT/event_helpers.txt"
echo "== image formation record (renderer parity)"
"$PY" benchmarks/bench_image_formation.py record "$OUT/if_gpu" 2>&1 | tail -5
rm -rf "$OUT/tmp"
