#!/usr/bin/env bash
# The GPU checks of issue #44, as one script for a lent machine (docs/performance.md, "The GPU path").
#
# Here:   ../shared/tools/device-wheels && pip wheel . --no-deps --no-build-isolation -w .whl
# There:  bash benchmarks/gpu_checks.sh      (writes its logs and JSON rows under $OUT)
#
# 1. `wfbench train --device cuda` as documented, with its defaults (scale-free, bf16), with
#    each older network by name, with --compile, and with IMPALA and hindsight learning;
# 2. benchmarks/train_speed.py on CUDA (bf16; B = 8192 and 16384; paper at B = 4096), the profile
#    (benchmarks/profile_rollout.py, B = 16384), the CPU cores, then --compile (the slowest, last).
# Each step has its own timeout, so one failure costs its step only.
set -u
OUT=${OUT:-/tmp/gpu-out}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1 NUMBA_CACHE_DIR=/tmp/numba-cache TQDM_DISABLE=1
if [ -d .whl ]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
    || exit 1
  export PYTHONPATH=/tmp/site PATH=/tmp/site/bin:$PATH
fi
log="$OUT/checks.log"
step() {  # step SECONDS NAME COMMAND...: run, time, log its tail and status
  local limit=$1 name=$2; shift 2
  local t0=$SECONDS
  echo "=== $name: $*" | tee -a "$log"
  timeout "$limit" "$@" >"/tmp/$name.out" 2>&1
  local rc=$?
  { echo "=== $name"; cat "/tmp/$name.out"; } >>"$OUT/full.log"
  tail -n 12 "/tmp/$name.out" | grep -v '^USDT' | tee -a "$log"
  echo "=== $name: rc $rc in $((SECONDS - t0)) s" | tee -a "$log"
}
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | tee -a "$log"
python3 -c "import torch; print('torch', torch.__version__, 'cuda', torch.version.cuda, 'cudnn',
torch.backends.cudnn.version(), 'cores', __import__('os').cpu_count())" | tee -a "$log"

T="wfbench train --device cuda --scenario paper-64 --no-progress --no-tensorboard --eval-every 0"
step 90 train-default $T --steps 2048 --run-dir /tmp/r-default
for m in paper small cpu; do
  step 45 "train-$m" $T --model $m --steps 2048 --run-dir "/tmp/r-$m"
done
# docs/rl.md's GPU command (paper, B = 1024, T = 64, compiled), one update
step 120 train-paper-doc $T --model paper --compile --num-envs 1024 --num-steps 64 --epochs 3 --minibatches 4 \
  --steps 65536 --run-dir /tmp/r-paper-doc
step 45 train-impala $T --algo impala --steps 4096 --run-dir /tmp/r-impala
step 60 train-hindsight $T --algo hindsight --steps 2048 --run-dir /tmp/r-hindsight

S="python3 benchmarks/train_speed.py --device cuda --bf16 --scenario paper-64 --threads 1 --num-steps 32"
step 60 speed-scalefree $S --models scalefree --num-envs 8192 --updates 2 --json "$OUT/speed-sf-8192.json"
step 75 speed-scalefree-16k $S --models scalefree --num-envs 16384 --updates 2 --json "$OUT/speed-sf-16384.json"
step 90 speed-paper $S --models paper --num-envs 4096 --updates 1 --json "$OUT/speed-paper-4096.json"
step 100 profile python3 benchmarks/profile_rollout.py --device cuda --bf16 --num-envs 16384 --out "$OUT/profile.txt"
step 90 speed-cpu python3 benchmarks/train_speed.py --device cpu --threads 16 --models scalefree --num-envs 1024 \
  --updates 2 --json "$OUT/speed-cpu16.json"
step 150 speed-compiled $S --models scalefree --num-envs 16384 --updates 2 --compile --json "$OUT/speed-sf-compiled.json"
