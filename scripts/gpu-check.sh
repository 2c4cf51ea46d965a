#!/usr/bin/env bash
# The whole GPU measurement in one call, from the prebuilt binaries that scripts/gpu-pack.sh
# put in .gpu/ (the GPU machine reaches no registry and builds nothing). In order of value:
#   1. the machine: GPU name, memory, driver; the wgpu adapter;
#   2. wgpu parity against the CPU reference on this GPU (gs-raster's wgpu_parity tests, the
#      loss kernels' tests: gs-mvs photometric_gpu (L_p) and feature_gpu (L_f), gs-losses image_gpu (L_I) and
#      normal_gpu (L_nc / L_ns), the resident model's Adam: gs-raster wgpu_resident, renders
#      that guess their buffers: gs-raster wgpu_guessed_render, L_f's VGG16 maps: gs-features
#      vgg_gpu, both blend tile splits: gs-raster wgpu_tile_split, density control: gs-train
#      wgpu_densify, and gs-gpu's scan, sort and sums: gs-gpu device);
#   3. the rasterizer bench at 1920×1080 with 100k and 1M Gaussians, wgpu and 16 CPU threads;
#   4. the README job (built-in scene) twice on wgpu (are the model bytes the same?) and once
#      on the CPU, with per-phase times, held-out PSNR and veils;
#   5. synth-bunny, default settings, full resolution, on wgpu and on the CPU: training time,
#      per-phase times, held-out PSNR, mesh Chamfer / F1 (object protocol);
#   6. with the time left, the rasterizer at 100k with the blends' other tile splits.
# Each step is skipped (and says so) when the time budget left cannot hold it, so the call ends
# in time and the steps done still come back. Results: $OUT/gpu-check.md (one table per step)
# and a log per step.
#
#   bash scripts/gpu-check.sh                 # on the device, carry .gpu and .gl
#   GPU_CHECK_SMOKE=1 [GPU_CHECK_SKIP=parity,raster] bash scripts/gpu-check.sh
#                                             # smoke test anywhere: tiny runs, lavapipe too
set -uo pipefail
cd "$(dirname "$0")/.."
OUT="${OUT:-$PWD/gpu-check-out}"
mkdir -p "$OUT"
budget="${GPU_CHECK_BUDGET_S:-470}"
smoke="${GPU_CHECK_SMOKE:-0}"
start=$(date +%s)
W="${TMPDIR:-/tmp}/gpu-check-runs"
rm -rf "$W" && mkdir -p "$W/bin"
B="$W/bin"
# The binaries: one solid xz archive (gpu-pack.sh), unpacked by Python's tarfile, else by tar.
unpack='import sys, tarfile
t = tarfile.open(sys.argv[1])
t.extractall(sys.argv[2], **({"filter": "data"} if hasattr(tarfile, "data_filter") else {}))'
{ command -v python3 >/dev/null && python3 -c "$unpack" .gpu/bin.tar.xz "$B"; } || tar -xJf .gpu/bin.tar.xz -C "$B"
chmod +x "$B"/*
summary="$OUT/gpu-check.md"
export RAYON_NUM_THREADS="${RAYON_NUM_THREADS:-$(nproc)}"
left() { echo $(( budget - ($(date +%s) - start) )); }
note() { echo "$*" | tee -a "$summary"; }

# The Vulkan loader travels as Debian packages (.gl, see scripts/gpu-pack.sh).
if ! ldconfig -p 2>/dev/null | grep -q libvulkan.so.1 && ls .gl/*.deb >/dev/null 2>&1; then
  for f in .gl/*.deb; do dpkg -x "$f" /; done
  ldconfig
fi
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[ -f "$icd" ] && export VK_DRIVER_FILES="$icd"

: > "$summary"
note "# gpu-check $(date -u +%Y-%m-%dT%H:%MZ), binaries of $(tr '\n' ' ' < .gpu/commit 2>/dev/null)"
note ""
note "machine: $(nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>/dev/null || echo 'no nvidia-smi')," \
  "$(nproc) host cores, RAYON_NUM_THREADS=$RAYON_NUM_THREADS, budget ${budget} s"

# step NAME SECONDS CMD...: runs CMD (log in $OUT/NAME.log) when SECONDS fit in the budget left.
step() {
  local name="$1" need="$2"; shift 2
  case ",${GPU_CHECK_SKIP:-}," in *",$name,"*) note ""; note "## $name: SKIPPED (GPU_CHECK_SKIP)"; return 1 ;; esac
  if [ "$(left)" -lt "$need" ]; then
    note ""; note "## $name: SKIPPED (needs ~${need} s, $(left) s left in the budget)"; return 1
  fi
  local t0; t0=$(date +%s)
  # Never past the budget: a hung step is ended, and the steps done still come back.
  timeout -k 5 "$(left)" bash -c '"$@"' _ "$@" > "$OUT/$name.log" 2>&1
  local rc=$?
  echo "$name: exit $rc in $(( $(date +%s) - t0 )) s" >> "$OUT/steps.txt"
  return $rc
}

# 2. Parity on this GPU.
step parity 60 env CI=true "$B/wgpu-parity" --test-threads 1; r=$?
if [ -f "$OUT/parity.log" ]; then
  if [ $r = 0 ]; then r=passed; else r=FAILED; fi
  note ""; note "## wgpu parity: $r ($(grep -E '^test result' "$OUT/parity.log" | tail -1))"
fi

# The loss kernels and the resident model's Adam against their CPU twins (gs-mvs
# photometric_gpu and feature_gpu, gs-losses image_gpu and normal_gpu, gs-raster wgpu_resident,
# gs-features vgg_gpu), renders that guess their buffers against counted ones (gs-raster
# wgpu_guessed_render), both blend tile splits against the CPU (gs-raster wgpu_tile_split),
# density control on the resident model against the host's rule (gs-train wgpu_densify: clone,
# split, prune, the trim's counts, the capture path's test), and gs-gpu's scan, sort and
# compensated sums (gs-gpu device).
for t in lp lf image normal resident guess vgg split densify sums; do
  step ${t}_parity 30 env CI=true "$B/$t-parity" --test-threads 1 --nocapture; r=$?
  if [ -f "$OUT/${t}_parity.log" ]; then
    if [ $r = 0 ]; then r=passed; else r=FAILED; fi
    note ""; note "## $t kernel parity: $r ($(grep -E '^test result' "$OUT/${t}_parity.log" | tail -1))"
    grep -E "relative" "$OUT/${t}_parity.log" | sed 's/^/    /' >> "$summary"
  fi
done

# 3. Rasterizer bench at 1920×1080.
counts=100000,1000000; size=1920x1080; [ "$smoke" = 1 ] && counts=2000 && size=160x120
if step raster 150 env GS_RASTER_WGPU_REPORT=1 GS_RASTER_CPU_REPORT=1 GS_RASTER_BENCH_SIZE=$size \
    GS_RASTER_BENCH_COUNTS=$counts "$B/raster-bench" --bench raster_wgpu; then
  note ""; note "## Rasterizer, $size, SH degree 3 (ms per call; wgpu: mean of 5 after a warm-up, CPU: of 10)"
  grep -E "^(wgpu adapter|n=|wgpu n=)" "$OUT/raster.log" | sed 's/^/    /' >> "$summary"
fi
# The previous commit's bench beside it (gpu-pack.sh --baseline-bench), wgpu rows only.
if [ -x "$B/raster-bench-baseline" ] && step raster_baseline 60 env GS_RASTER_WGPU_REPORT=1 \
    GS_RASTER_BENCH_SIZE=$size GS_RASTER_BENCH_COUNTS=$counts "$B/raster-bench-baseline" --bench raster_wgpu; then
  note ""; note "## Rasterizer, the baseline binary ($(cat .gpu/baseline 2>/dev/null)), same runs"
  grep -E "^wgpu n=" "$OUT/raster_baseline.log" | sed 's/^/    /' >> "$summary"
fi

# train_job TAG BACKEND SCENE... : train + eval-images (+ mesh and eval-mesh for a GT mesh).
train_job() {
  local tag="$1" backend="$2" bin="$3"; shift 3
  local run="$W/$tag"
  local iters=(); [ "$smoke" = 1 ] && iters=(--iterations 60)
  "$bin" train "$@" -o "$run" --eval --backend "$backend" "${iters[@]}" --quiet &&
    "$bin" eval-images "$run" --no-lpips --backend "$backend" --json > "$run/eval.json" || return 1
  local gt="${GT_MESH:-}"
  if [ -n "$gt" ]; then
    "$bin" mesh "$run" --backend "$backend" &&
      "$bin" eval-mesh --pred "$run/mesh.ply" --gt "$gt" --crop-to-gt 0.05 --min-z 0.005 --json > "$run/eval_mesh_out.json"
  fi
}
export -f train_job; export W B smoke
readme_need=70; bunny_need=230; [ "$smoke" = 1 ] && readme_need=20 && bunny_need=30

# 4. README job: wgpu twice, CPU once (and the baseline binary, when packed).
# 4 and 5 in order of value: the README job twice on wgpu, synth-bunny on wgpu, then the CPU
# runs (the CPU path's bytes are fixed by the identity tests; its times were measured before).
bunny=.gpu/data/synth-bunny
step readme_wgpu_1 "$readme_need" train_job readme_wgpu_1 wgpu "$B/vagsl"
step readme_wgpu_2 "$readme_need" train_job readme_wgpu_2 wgpu "$B/vagsl"
[ -d "$bunny" ] && GT_MESH="$bunny/gt_mesh.ply" step bunny_wgpu "$bunny_need" train_job bunny_wgpu wgpu "$B/vagsl" "$bunny"
# The baseline binary (gpu-pack.sh --baseline) on synth-bunny beside the new one, else on the
# README job: a speed-up is a ratio measured on one machine.
if [ -x "$B/vagsl-baseline" ]; then
  if [ -d "$bunny" ]; then
    GT_MESH="$bunny/gt_mesh.ply" step bunny_wgpu_baseline "$bunny_need" train_job bunny_wgpu_baseline wgpu "$B/vagsl-baseline" "$bunny"
  else
    step readme_wgpu_baseline "$readme_need" train_job readme_wgpu_baseline wgpu "$B/vagsl-baseline"
  fi
fi
step readme_cpu "$readme_need" train_job readme_cpu cpu "$B/vagsl"
# What `--backend auto` picks for the README job (report.json's backend_choice: the step it
# timed on each backend), below the training table.
step readme_auto 40 "$B/vagsl" train -o "$W/readme_auto" --iterations 60 --quiet
if [ -f "$W/readme_wgpu_1/point_cloud.ply" ] && [ -f "$W/readme_wgpu_2/point_cloud.ply" ]; then
  if cmp -s "$W/readme_wgpu_1/point_cloud.ply" "$W/readme_wgpu_2/point_cloud.ply"; then same="the same bytes"; else same="DIFFERENT bytes"; fi
  note ""; note "two wgpu runs of the README job, one seed: point_cloud.ply has $same"
fi

[ -d "$bunny" ] && GT_MESH="$bunny/gt_mesh.ply" step bunny_cpu "$bunny_need" train_job bunny_cpu cpu "$B/vagsl" "$bunny"

# 6. The blends' other tile splits on this GPU, with what time is left: forward 64 threads of 4
# pixels and backward 64 of 4, then software Vulkan's 16 of 16 in both, at 100k Gaussians,
# to choose the GPU's split on a measurement (docs/architecture.md §GPU).
split_counts=100000; [ "$smoke" = 1 ] && split_counts=2000
for split in 64,64 16,16; do
  if step "raster_split_${split/,/_}" 40 env GS_RASTER_WGPU_REPORT=1 GS_RASTER_TILE_SPLIT=$split \
      GS_RASTER_BENCH_SIZE=$size GS_RASTER_BENCH_COUNTS=$split_counts "$B/raster-bench" --bench raster_wgpu; then
    note ""; note "## Rasterizer, $size, tile split $split (forward, backward threads per tile)"
    grep -E "^(wgpu adapter|wgpu n=)" "$OUT/raster_split_${split/,/_}.log" | sed 's/^/    /' >> "$summary"
  fi
done

# The training table: one row per run that finished.
python3 - "$W" >> "$summary" <<'EOF'
import json, os, sys
w = sys.argv[1]
rows = []
prof = []  # where an iteration's time goes (report.json's time_by_part, gs_train::profile)
for tag in sorted(os.listdir(w)):
    d = os.path.join(w, tag)
    try:
        rep = json.load(open(os.path.join(d, "report.json")))
    except (OSError, ValueError):
        continue
    def load(name):
        try:
            return json.load(open(os.path.join(d, name)))
        except (OSError, ValueError):
            return None
    ev, em = load("eval.json"), load("eval_mesh_out.json")
    ph = rep.get("phase_seconds", [0, 0, 0, 0])
    worst = min(ev["views"], key=lambda v: v["psnr"]) if ev and ev.get("views") else None
    veils = sum(1 for v in ev["views"] if v.get("veil")) if ev else 0
    rows.append("| {} | {:.1f} s | {:.1f} / {:.1f} / {:.1f} s | {} | {} | {} | {} | {} |".format(
        tag, rep["train_seconds"], ph[0], ph[1], ph[3], rep["gaussians"],
        f"{ev['psnr']:.2f} dB" if ev else "—",
        f"{worst['name']} {worst['psnr']:.2f} dB" if worst else "—", veils,
        f"{em['chamfer']:.5f} / {em['f1']:.3f}" if em else "—"))
    for phase, e in rep.get("time_by_part", {}).items():
        ms = e["ms_per_iteration"]
        top = sorted(((v, k) for k, v in ms.items() if k != "whole"), reverse=True)
        t = e.get("transfers_per_iteration")
        traffic = "{:.2f} waits, {:.0f} KB back, {:.0f} KB up".format(t["syncs"], t["bytes_read_back"] / 1e3, t["bytes_written"] / 1e3) if t else "—"
        prof.append("| {} | {} | {} | {:.1f} | {} | {} |".format(tag, phase, e["iterations"], ms["whole"],
            ", ".join(f"{k} {v:.1f}" for v, k in top if v >= 0.01 * ms["whole"]), traffic))
if rows:
    print("\n## Training runs (train time; warm-up / L_p / refinement seconds; held-out PSNR without LPIPS)\n")
    print("| run | train | warm-up / L_p / refine | Gaussians | held-out PSNR | worst view | veils | Chamfer / F1 |")
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
choices = []
for tag in sorted(os.listdir(w)):
    try:
        c = json.load(open(os.path.join(w, tag, "report.json"))).get("backend_choice")
    except (OSError, ValueError):
        continue
    if c and c.get("probe"):
        p = c["probe"]
        choices.append("{}: chose {} ({}); the step of iteration {} on {} Gaussians took {:.1f} ms on wgpu and {:.1f} ms on the CPU".format(
            tag, c["chosen"], c["device"], p["iteration"], p["gaussians"], p["wgpu_ms"], p["cpu_ms"]))
if choices:
    print("\n## --backend auto\n")
    print("\n".join(choices))
if prof:
    print("\n## Where an iteration's time goes (ms per iteration, parts of at least 1 %; host-device traffic per iteration)\n")
    print("| run | phase | iterations | ms each | parts | traffic |")
    print("|---|---|---|---|---|---|")
    print("\n".join(prof))
EOF
note ""
note "total $(( $(date +%s) - start )) s"
cat "$OUT/steps.txt" 2>/dev/null
