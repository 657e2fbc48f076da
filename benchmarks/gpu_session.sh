#!/usr/bin/env bash
# One GPU session in one call: install hairlut beside JAX for CUDA, run the tests on the GPU and the
# GPU figures the open issues ask for, and leave JSON and logs under $OUT (at most 8 files).
#
#   here, once (a machine that reaches the package registries; the GPU machine does not):
#       bash benchmarks/gpu_session.sh --fetch-wheels      # .whl/: OpenEXR, flip-evaluator, h5netcdf for cp312
#   on the GPU machine (the device tool's run, with carry [".whl"] and timeout_s about budget + 40):
#       bash benchmarks/gpu_session.sh [--budget 530]
#   and, if the machine is still warm and time is left, what the first call had no time for, e.g.:
#       bash benchmarks/gpu_session.sh --only tests-rest --budget 240
#   a dry run on a CPU, every size shrunk, to know the script works end to end:
#       OUT=/tmp/gpu-dry bash benchmarks/gpu_session.sh --small [--budget 2400] [--only STEP,STEP]
#
# Order (each step has a cap and the whole run a deadline: a step that would pass it is cut short with
# SIGINT, so pytest still prints what it ran; what no longer fits is skipped and said so):
#   1. setup: a venv that sees the machine's JAX (python3 -m venv + a .pth to its site-packages), the
#      carried wheels and hairlut (editable) installed into it; JAX for CUDA from .whl/jax* or the
#      registry only where the machine's own does not see a GPU;
#   2. the tests whose numbers differ on a GPU (issue 15's precision list, the bake, the chunk writer);
#   3. the figures: issue 15 (default HRIR database through the CLI, cold and after compilation; 16,384
#      sectors; the paper-scale online frame; exact radiance of 10^6 vertices in float64), issue 13 (the
#      layered paper-scale 1024^2 render), issue 12 (the direct paper-scale frame), issue 16 (one device's
#      throughput on the production recipe, and the 8-GPU projection), `hairlut stress --only gpu`;
#   4. the rest of the test suite, slow tests included, with the time left.
# Files under $OUT: summary.json (every step: rc, wall, cap, figures), summary.md (each step's tail),
# machine.json, tests-gpu.log, tests-rest.log, logs.tar.gz (every step's full output), results.tar.gz
# (benchmarks/results/*.json).
set -u
cd "$(dirname "$0")/.."
ROOT=$PWD
SMALL=0; BUDGET=530; FETCH=0; ONLY=""
while [ $# -gt 0 ]; do
  case "$1" in
    --small) SMALL=1 ;;
    --budget) BUDGET=$2; shift ;;
    --fetch-wheels) FETCH=1 ;;
    --only) ONLY=",$2,"; shift ;;
    *) echo "usage: $0 [--small] [--budget SECONDS] [--only STEP,STEP] | --fetch-wheels" >&2; exit 2 ;;
  esac
  shift
done

if [ $FETCH = 1 ]; then  # wheels the GPU machine lacks (its packages: /work/.library/device/KINDS.md)
  mkdir -p .git/info && { grep -qx '/.whl/' .git/info/exclude 2>/dev/null || echo /.whl/ >> .git/info/exclude; }
  exec python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
    -d .whl OpenEXR==3.5.3 flip-evaluator==1.7 h5netcdf==1.8.2
fi

START=$(date +%s); DEADLINE=$((START + BUDGET)); RESERVE=15
OUT=${OUT:-$ROOT/out/gpu-session}; mkdir -p "$OUT"
WORK=$(mktemp -d); LOGS=$WORK/logs; mkdir -p "$LOGS"; STEPS=$WORK/steps.jsonl; : > "$STEPS"
export PYTHONUNBUFFERED=1 XLA_PYTHON_CLIENT_PREALLOCATE=false HAIRLUT_NO_SPLASH=1
[ $SMALL = 1 ] && export JAX_PLATFORMS=cpu

left() { echo $((DEADLINE - $(date +%s) - RESERVE)); }

summary() {  # summary.json and summary.md from the steps so far (cheap: no JAX)
  python3 - "$STEPS" "$LOGS" "$OUT" "$SMALL" <<'PY'
import json, sys, pathlib
steps_file, logs, out, small = sys.argv[1], pathlib.Path(sys.argv[2]), pathlib.Path(sys.argv[3]), sys.argv[4] == "1"
steps = [json.loads(line) for line in open(steps_file) if line.strip()]
for s in steps:  # a bake's --json report, where the step printed one
    p = logs / f"{s['name']}.out"
    if p.exists():
        text = p.read_text(errors="replace").strip()
        try:
            rep = json.loads(text[text.index("{"):])
        except ValueError:
            continue
        s["report"] = {k: rep.get(k) for k in ("sectors", "computed", "seconds", "blocks_s", "assemble_s", "bytes",
                                               "block_seconds") if k in rep}
    p = logs / f"{s['name']}.json"
    if p.exists():
        try:
            s["figures"] = json.loads(p.read_text())
        except ValueError:
            pass
doc = {"small": small, "steps": steps}
m = out / "machine.json"
if m.exists():
    try:
        doc["machine"] = json.loads(m.read_text())
    except ValueError:
        pass
(out / "summary.json").write_text(json.dumps(doc, indent=1, default=str))
md = [f"# GPU session{' (dry run, --small)' if small else ''}", ""]
for s in steps:
    md.append(f"## {s['name']}: rc {s['rc']}, {s['wall_s']:.1f} s (cap {s['cap_s']} s){' SKIPPED' if s.get('skipped') else ''}")
    md.append(f"`{s['cmd']}`")
    for suffix in (".log", ".out"):
        p = logs / f"{s['name']}{suffix}"
        if p.exists():
            tail = p.read_text(errors="replace").splitlines()[-25:]
            md += ["```", *tail, "```"]
    md.append("")
(out / "summary.md").write_text("\n".join(md))
PY
}

# step NAME CAP CMD...: run CMD with at most CAP seconds (CAP_SCALE times that with --small, where a shared
# CPU compiles slowly; less if the deadline is nearer); stdout to NAME.out when the step is a bake (--json),
# else both streams to NAME.log
CAP_SCALE=1; [ $SMALL = 1 ] && CAP_SCALE=4
step() {
  local name=$1 cap=$(($2 * CAP_SCALE)); shift 2
  [ -n "$ONLY" ] && [ "${ONLY#*,$name,}" = "$ONLY" ] && return  # --only: not this step
  local t; t=$(left); [ "$cap" -lt "$t" ] && t=$cap
  local cmd="$*"
  if [ "$t" -lt 10 ]; then
    printf '{"name": "%s", "rc": null, "wall_s": 0, "cap_s": %d, "skipped": true, "cmd": %s}\n' \
      "$name" "$cap" "$(python3 -c 'import json,sys; print(json.dumps(sys.argv[1]))' "$cmd")" >> "$STEPS"
    echo "== $name: skipped (no time left)"; summary; return
  fi
  echo "== $name (cap ${t} s): $cmd"
  local t0; t0=$(date +%s.%N)
  case "$cmd" in
    *--json*) timeout -s INT -k 20 "$t" "$@" > "$LOGS/$name.out" 2> "$LOGS/$name.log" ;;
    *) timeout -s INT -k 20 "$t" "$@" > "$LOGS/$name.log" 2>&1 ;;
  esac
  local rc=$?
  local wall; wall=$(python3 -c "import time; print(round(time.time() - $t0, 2))")
  printf '{"name": "%s", "rc": %d, "wall_s": %s, "cap_s": %d, "cmd": %s}\n' "$name" "$rc" "$wall" "$t" \
    "$(python3 -c 'import json,sys; print(json.dumps(sys.argv[1]))' "$cmd")" >> "$STEPS"
  echo "   rc $rc, ${wall} s"; tail -n 4 "$LOGS/$name.log" 2>/dev/null | sed 's/^/   | /'
  summary
}

# ---------------------------------------------------------------------------------------------- 1. setup
BASE=${PYTHON:-python3}
[ $SMALL = 1 ] && [ -x "$ROOT/.venv/bin/python" ] && BASE=$ROOT/.venv/bin/python
VENV=$WORK/venv
setup() {
  "$BASE" -m venv --without-pip "$VENV" || return 1
  local site; site=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
  "$BASE" -c 'import site, sys; print("\n".join(p for p in site.getsitepackages() + [site.getusersitepackages()]))' \
    > "$site/_base_python.pth"  # the machine's packages (JAX for CUDA, NumPy, h5py, pytest, ...) stay visible
  local py="$VENV/bin/python"
  if ls .whl/*.whl > /dev/null 2>&1; then
    "$py" -m pip install -q --no-index --no-deps --no-compile .whl/*.whl || return 1
  fi
  "$py" -m pip install -q --no-index --no-deps --no-build-isolation -e . || return 1
  if [ $SMALL = 0 ] && ! "$py" -c 'import jax, sys; sys.exit(0 if any(d.platform == "gpu" for d in jax.devices()) else 1)'; then
    if ls .whl/jax*.whl > /dev/null 2>&1; then "$py" -m pip install -q --no-index .whl/jax*.whl
    else "$py" -m pip install -q -e '.[cuda]'; fi  # needs the registry
  fi
  "$py" -c 'import jax, hairlut; print("jax", jax.__version__, jax.devices(), "hairlut", hairlut.__file__)'
}
t0=$(date +%s.%N)
if setup > "$LOGS/setup.log" 2>&1; then PY=$VENV/bin/python; HL=$VENV/bin/hairlut; rc=0
else  # the recipe of shared/GPU.md: PYTHONPATH instead of a venv
  rc=$?; PY=$BASE; pp=$WORK/pp; mkdir -p "$pp"; ln -sf "$ROOT/cli" "$pp/hairlut_cli"
  if ls .whl/*.whl > /dev/null 2>&1; then "$PY" -m pip install -q --no-index --no-deps --target "$WORK/site" .whl/*.whl; fi
  export PYTHONPATH=$WORK/site:$pp:$ROOT${PYTHONPATH:+:$PYTHONPATH}; HL=$WORK/hairlut
  printf '#!/bin/sh\nexec "%s" -c "import sys; from hairlut_cli.main import main; sys.argv[0] = \\"hairlut\\"; main()" "$@"\n' \
    "$PY" > "$HL"; chmod +x "$HL"
  echo "venv setup failed (rc $rc): PYTHONPATH fallback" >> "$LOGS/setup.log"
fi
printf '{"name": "setup", "rc": %d, "wall_s": %s, "cap_s": 120, "cmd": "venv + wheels + pip install -e ."}\n' "$rc" \
  "$(python3 -c "import time; print(round(time.time() - $t0, 2))")" >> "$STEPS"
cat "$LOGS/setup.log" | tail -n 3
"$PY" - > "$OUT/machine.json" 2> "$LOGS/machine.log" <<'PY'
import json
from hairlut.bench import machine
print(json.dumps(machine(), indent=1, default=str))
PY
summary

# ------------------------------------------------------------------------------ 2. GPU-relevant tests
GPU_TESTS="tests/test_precision.py tests/test_density.py tests/test_hrir_tracer.py tests/test_sh_tables.py
           tests/test_chunk_writer.py tests/test_hrir_bake.py tests/test_stress.py"
XDIST="-n 8"; "$PY" -c 'import xdist' 2>/dev/null || XDIST=""
if [ $SMALL = 1 ]; then
  step tests-gpu 240 "$PY" -m pytest -q -p no:cacheprovider -m "not slow" tests/test_chunk_writer.py
else
  step tests-gpu 120 "$PY" -m pytest -q -p no:cacheprovider $XDIST -rfE $GPU_TESTS
fi
cp "$LOGS/tests-gpu.log" "$OUT/tests-gpu.log" 2>/dev/null

# ------------------------------------------------------------------------------------------ 3. figures
T=$WORK/assets; mkdir -p "$T"
if [ $SMALL = 1 ]; then
  TINY="--set angles.views=8 --set angles.lights=8 --set trace.pixels=16 --set trace.steps=16"
  DEFAULT="--set sectors.count=64 $TINY"; BIG="--set sectors.count=192 $TINY"
  PROD=(64 16 16 16); QUICK=--quick; PAPER="--resolution 128 --texels 16"
else
  DEFAULT=""; BIG="--set sectors.count=16384"; PROD=(512 64 64 64); QUICK=""; PAPER=""
fi
# issue 15: the default database through the CLI, cold (compiles), then again with JAX's compilation cache
export JAX_COMPILATION_CACHE_DIR=$WORK/jax-cache JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS=0 \
       JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES=0
step hrir-default-cold 120 $HL bake hrir --out "$T/default-1.h5" --no-progress --json $DEFAULT
step hrir-default-warm 90 $HL bake hrir --out "$T/default-2.h5" --no-progress --json $DEFAULT
step hrir-16384 180 $HL bake hrir --out "$T/big.h5" --no-progress --json $BIG
unset JAX_COMPILATION_CACHE_DIR JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES
# the studies of `hairlut bench` that the GPU figures need, one each, their records in $LOGS/NAME.json
cat > "$WORK/study.py" <<'PY'
import json, sys, tempfile
from pathlib import Path
import hairlut.bench as hb
name, out, quick = sys.argv[1], Path(sys.argv[2]), "--quick" in sys.argv[3:]
if name == "online-frame":  # the maps part's online frame (the paper's model unless --quick)
    doc = hb.online_frame_study(quick)
else:  # the sh part's radiance table: exact radiance of 10^6 vertices in float64, beside dense tables
    with tempfile.TemporaryDirectory() as d:
        ctx = hb.Context(quick=quick, workdir=Path(d))
        doc = {"figures": [f.to_json() for f in hb.sh_radiance_figures(ctx)], "notes": ctx.notes}
print(json.dumps(doc, indent=1, default=str))
out.write_text(json.dumps(doc, default=str))
PY
step online-frame 120 "$PY" "$WORK/study.py" online-frame "$LOGS/online-frame.json" $QUICK
step radiance-1e6-f64 90 "$PY" "$WORK/study.py" radiance "$LOGS/radiance-1e6-f64.json" $QUICK
step render-paper-1024 150 "$PY" -m benchmarks.paper_render $PAPER
step direct-frame 90 "$PY" -m benchmarks.frame_methods --methods direct $QUICK
# issue 16: one device's steady throughput on the production recipe (64 x 64 angles, 64 px, float16)
cat > "$WORK/production.py" <<'PY'
import json, statistics, sys, tempfile, time
from pathlib import Path
import jax
from hairlut.hrir import bake
count, views, lights, block = (int(x) for x in sys.argv[1:5])
recipe = {"sectors": {"count": count}, "angles": {"views": views, "lights": lights}, "storage": {"dtype": "float16"}}
with tempfile.TemporaryDirectory() as d:
    t = time.perf_counter()
    rep = bake(recipe, Path(d) / "prod.h5", block=block)
    wall = time.perf_counter() - t
steady = block / statistics.median(rep["block_seconds"][1:] or rep["block_seconds"])  # the first block compiles
prod = 65536 * 64 * 64 / (views * lights)  # production sectors in units of this recipe's tracing work
out = {"device": str(jax.devices()[0]), "sectors": count, "views": views, "lights": lights, "block": block,
       "wall_s": wall, "blocks_s": rep["blocks_s"], "assemble_s": rep.get("assemble_s"),
       "steady_sectors_per_s": steady, "production_minutes_on_8_devices": prod / steady / 8 / 60}
print(json.dumps(out, indent=1))
Path(sys.argv[5]).write_text(json.dumps(out))
PY
step production-rate 120 "$PY" "$WORK/production.py" "${PROD[@]}" "$LOGS/production-rate.json"
step stress-gpu 90 $HL stress --only gpu

# --------------------------------------------------------------------------------- 4. the other tests
if [ $SMALL = 1 ]; then
  step tests-rest 300 "$PY" -m pytest -q -p no:cacheprovider -m "not slow" tests/test_registry.py
else
  IGNORE="--ignore=tests/test_packaging.py"; for f in $GPU_TESTS; do IGNORE="$IGNORE --ignore=$f"; done
  step tests-rest 600 "$PY" -m pytest -q -p no:cacheprovider $XDIST -rfE -k "not usd" $IGNORE tests
fi
cp "$LOGS/tests-rest.log" "$OUT/tests-rest.log" 2>/dev/null

# ------------------------------------------------------------------------------------------- bundle
summary
tar -czf "$OUT/logs.tar.gz" -C "$WORK" logs
[ -d benchmarks/results ] && tar -czf "$OUT/results.tar.gz" -C benchmarks results
echo "done in $(( $(date +%s) - START )) s; $OUT: $(ls "$OUT" | tr '\n' ' ')"
