#!/usr/bin/env bash
# The GPU check of the learned methods (issue 60), about 5 minutes on one H100/H200:
#   1. the device-parametrised tests (tests/methods/test_devices.py, the trainer's resume) on cpu and cuda;
#   2. short `run.py` runs of gaps, gensim and vae with device=cuda on one garment (small budgets, reference=none,
#      viz=none); the VAE trains on simulated reference drapes, so its run needs warp and Newton (skipped without);
#   3. a training step of GAPS and GenSim timed on cuda and on the CPU (benchmarks/bench_train_step.py);
#   4. every run's metrics.json and this script's log copied into $OUT.
# A failing step is reported (FAILED in the log and the summary) and the next one runs; the exit status is the
# number of failed steps.
#
# Run from the repository root:   OUT=/path/to/results bash benchmarks/gpu_check.sh
# Environment: DEVICE (cuda; DEVICE=cpu tries the script on a machine without a GPU), OUT (default ./gpu_check_out),
# PYTHON (default python3), STEPS (training steps of each run, default 30), DRAPEBENCH_DATA (the data folder, default a
# fresh temporary one; a copy of data/cache/garments there spares a machine without pymeshlab the remeshing).
set -u
cd "$(dirname "$0")/.."
DEVICE=${DEVICE:-cuda}
OUT=${OUT:-$PWD/gpu_check_out}
PY=${PYTHON:-python3}
STEPS=${STEPS:-30}
WORK=$(mktemp -d)
mkdir -p "$OUT"
LOG="$OUT/gpu_check.log"
: >"$LOG"
export DRAPEBENCH_DATA="${DRAPEBENCH_DATA:-$WORK/data}" DRAPEBENCH_PROGRESS=0 RERUN_ANALYTICS=0 PYTHONUNBUFFERED=1 HYDRA_FULL_ERROR=1
export WARP_CACHE_PATH="$WORK/warp" PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"  # the package need not be installed
FAILED=()

step() {  # step NAME COMMAND...: run, log, time; a failure is recorded and the script goes on
  local name=$1
  shift
  echo "=== $name: $*" | tee -a "$LOG"
  local t0=$SECONDS
  if "$@" >>"$LOG" 2>&1; then
    echo "=== $name: ok ($((SECONDS - t0)) s)" | tee -a "$LOG"
  else
    echo "=== $name: FAILED (exit $?, $((SECONDS - t0)) s; the log above says why)" | tee -a "$LOG"
    FAILED+=("$name")
  fi
}

copy_metrics() {  # copy_metrics NAME: the run's metrics.json (or failed.json) into $OUT
  for f in metrics.json failed.json; do
    [ -f "$WORK/runs/$1/$f" ] && cp "$WORK/runs/$1/$f" "$OUT/${1}_$f"
  done
  return 0
}

{
  echo "gpu_check: device=$DEVICE, commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown), $(date -u)"
  nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>/dev/null || echo "no nvidia-smi"
  "$PY" -c "import torch; print('torch', torch.__version__, 'cuda', torch.version.cuda, 'available', torch.cuda.is_available())"
} 2>&1 | tee -a "$LOG"

# 1. device-parametrised tests: cuda is added to cpu where torch sees a GPU
step tests "$PY" -m pytest -q -p no:cacheprovider tests/methods/test_devices.py \
  "tests/train/test_trainer.py::test_an_interrupted_run_resumes_from_its_checkpoint_and_ends_where_an_uninterrupted_run_ends"

# 2. short runs on one garment (the low-resolution body, 20 frames of walk), each into its own folder
RUN=("$PY" run.py experiment=smoke "device=$DEVICE" reference=none viz=none tracker=none motion=walk "train.steps=$STEPS")
step run_gaps "${RUN[@]}" method=gaps garment=skirt ++method.params.relax_components=1 ++method.params.relax_iterations=20 \
  "hydra.run.dir=$WORK/runs/gaps"
copy_metrics gaps
step run_gensim "${RUN[@]}" method=gensim garment=skirt "++method.params.train.garments=[[skirt,{}]]" \
  "++method.params.train.seeds=[1]" "++method.params.train.resolutions=[0.03]" ++method.params.train.sequences=1 \
  ++method.params.train.n_frames=20 ++method.params.train.frames_per_sequence=4 "hydra.run.dir=$WORK/runs/gensim"
copy_metrics gensim
if "$PY" -c "import warp, newton" >/dev/null 2>&1; then  # the reference drapes the VAE trains on are simulated (vbd)
  step run_vae "${RUN[@]}" method=vae garment=skirt "data.motions=[walk,dance]" data.per_motion=1 data.n_frames=10 \
    data.transition=5 data.n_jobs=4 ++method.params.diffused.steps=300 ++method.params.diffused.n_surface=4000 \
    ++method.params.diffused.n_shell=4000 ++method.params.sdf.steps=300 ++method.params.projection.steps=10 \
    ++method.params.vae.steps=100 ++method.params.regressor.pose_steps=100 "hydra.run.dir=$WORK/runs/vae"
  copy_metrics vae
else
  echo "=== run_vae: skipped (warp or newton missing: the VAE's reference drapes cannot be simulated; its training and drape on $DEVICE are checked by tests/methods/test_devices.py)" | tee -a "$LOG"
fi

# 3. one training step, timed on the device and on the CPU
step train_step_device "$PY" benchmarks/bench_train_step.py --device "$DEVICE" --steps 20
if [ "$DEVICE" != cpu ]; then
  step train_step_cpu "$PY" benchmarks/bench_train_step.py --device cpu --steps 12
fi
grep -h "ms/step" "$LOG" >"$OUT/train_step.txt" || true

echo "gpu_check: ${#FAILED[@]} failed step(s)${FAILED[*]:+: ${FAILED[*]}}; results in $OUT" | tee -a "$LOG"
rm -rf "$WORK"
exit "${#FAILED[@]}"
