#!/usr/bin/env bash
# The GPU check as one prepared run on a lent machine (see scripts/device_check.py); every stage
# has its own time limit and writes its log under $OUT as it goes.
#   bash scripts/device_check.sh            # on the device machine, from the repo root
# SMALL=1 shrinks every stage for a dry run on a CPU.
set -u
OUT=${OUT:-/tmp/device-out}; mkdir -p "$OUT"
export PYTHONUNBUFFERED=1 XLA_PYTHON_CLIENT_PREALLOCATE=false PYTHONPATH=$PWD
PY=${PY:-python3}
if [ "${SMALL:-0}" = 1 ]; then
  LANES=512,1024; BLOCKS=128; BIG=1024; N=2000; BOUND=8388608; BENCH=1000; T=(150 60 120 60 60 90); NDT=20000
  KT=128,256; KW=2,4; RS=65536,1048576; FS=134217728
  FIGS="5"; FIGQ=--quick; EVENTS=${EVENTS:-wait,fused}
  TESTS=tests/test_di_exact.py::test_float32_at_paper_values
else  # the H200 of 2026-11-30 (PERFORMANCE.md "On an H200"): the fused kernel alone ran 2.8e11 slot-steps/s (tile 256,
  # 4 warps: the best of 12) and a direct draw 8.3e10, yet a whole block ran ~1e10: first --breakdown splits
  # one block (draw, loop, bookkeeping) and tries GPU-sized rounds and final calls (PERFORMANCE.md "On an H200":
  # a run there made 30 rounds of <= 4 blocks and 20 one-block calls); then the layouts, float64 and the
  # bench, and the full-setting GPU times of the scenes no lease timed (Figs. 9, 8, 5, 1); the GPU tests
  # all passed there, so only the closed forms run again
  LANES=262144,131072; BLOCKS=1024,512; BIG=262144; N=200000; BOUND=1073741824; BENCH=100000
  T=(190 60 110 0 0 180); NDT=4000000; FIGS="9 8 5 1"; FIGQ=""; KT=256; KW=4
  RS=67108864,4294967296; FS=134217728,8589934592  # rounds of 2^26 (4 blocks here) and 2^32; calls 2^27, 2^33
  TESTS=tests/test_di_exact.py
fi
EVENTS=${EVENTS:-fused}  # the DI's default on an NVIDIA GPU; EVENTS=wait,fused compares them
{
  date -u; nvidia-smi -L 2>&1; nproc
  # no pip install: PYTHONPATH=$PWD, every stage runs "$PY -m", and the tests' subprocesses inherit it
  timeout 40 $PY -c 'import jax, numba, equinox, scipy; print("jax", jax.__version__, jax.devices(), "numba", numba.__version__, "equinox", equinox.__version__)'
} > "$OUT/env.log" 2>&1
cat "$OUT/env.log"
stage() {  # name limit command...
  local name=$1 lim=$2; shift 2
  local t=$(date +%s)
  # SIGINT first (dryfric prints what it reached and exits 130), SIGKILL 5 s later
  timeout -s INT -k 5 "$lim" "$@" > "$OUT/$name.log" 2>&1
  echo "== $name: rc $? in $(( $(date +%s) - t )) s (limit $lim)"; tail -4 "$OUT/$name.log"
}
# the DI's quiet loop as one Pallas kernel (dryfric_jax.fused), every layout
stage layouts32 "${T[0]}" $PY scripts/device_check.py --dtypes float32 --lanes $LANES --block $BLOCKS \
  --events $EVENTS --n $N --bound-n $BOUND --numba-n 16000 --budget-s $(( ${T[0]} - 60 )) --kernel-tiles $KT \
  --kernel-warps $KW --breakdown --round-steps $RS --final-call-steps $FS
[ "${T[1]}" -gt 0 ] && stage tests "${T[1]}" $PY -m pytest -q -p no:cacheprovider -rfE --durations=8 $TESTS
stage layouts64_bench "${T[2]}" $PY scripts/device_check.py --dtypes float64 --lanes $BIG --block 256,1024 \
  --events $EVENTS --n $N --bound-n $BOUND --numba-n 0 --bench-n $BENCH --budget-s $(( ${T[2]} - 80 )) \
  --kernel-tiles 256 --kernel-warps 4
# float32 against float64 with independent seeds (they differed by 0.39% on the H200, sharing keys,
# and by 0.27% on 2 CPU cores, 6e6 excursions each; here 4e6 each; the paired tests above bound the float32 chain's
# bias to 0.06% on a CPU: RESULTS.md "float32 against float64")
export PY NDT BIG
[ "${T[3]}" -gt 0 ] && stage dtypes "${T[3]}" bash -c 'for dt in float32 float64; do s=11; [ $dt = float64 ] && s=12
  $PY -m dryfric_jax.cli estimate --json --dtype $dt --seed $s --n-excursions $NDT --lanes $BIG --block 256 \
    --max-work 1e12; rc=$?; [ $rc = 130 ] && break; done; exit $rc'
[ "${T[4]}" -gt 0 ] && stage unroll32 "${T[4]}" $PY scripts/device_check.py --dtypes float32 --lanes $BIG \
  --block 256 --unroll 1,4 --events wait --n $N --bound-n $BOUND --numba-n 0 --budget-s $(( ${T[4]} - 30 ))
# issue 5: the path scenes at full settings (the README's CPU column), one after another until the limit;
# figures go to /tmp (too many files for $OUT), each scene's wall time from its JSON into the log
export FIGS FIGQ
# (the loops stop at the limit's SIGINT: dryfric exits 130 rather than dying of it, and the next item would be
# SIGKILLed, losing the summary)
stage figs "${T[5]}" bash -c 'for f in $FIGS; do t=$(date +%s); rc=0; $PY -m dryfric_jax.cli figures --fig $f $FIGQ \
  --out /tmp/figs > /dev/null || { rc=$?; echo "fig $f rc $rc"; }; echo "fig $f: $(( $(date +%s) - t )) s in all";
  [ $rc = 130 ] && break; done;
  $PY -c "import glob, json; [print(f, round(json.load(open(f))[\"wall_s\"], 1))
    for f in sorted(glob.glob(\"/tmp/figs/*.json\"))]"'
