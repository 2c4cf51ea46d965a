#!/usr/bin/env bash
# The validation suite: trains a preset on every generated suite scene (`vagsl synth`), meshes
# and scores it with the object protocol, and writes ONE markdown table, OUTDIR/suite.md.
#
#   scripts/suite.sh [--quick] [--preset P] [-o OUTDIR] [--scenes a,b] [--seed S] [--train-seed S]
#                    [--iterations N] [--threads T] [--jobs J] [--backend B] [--set KEY=VALUE]...
#                    [--remesh] [--mesh-arg ARG]...
#
# --quick     200x150 scenes instead of 480x360 (and --iterations, if given, for a shorter run)
# --preset    passed to `vagsl train` (default: train's own default preset)
# -o OUTDIR   where runs and the table go (default target/suite/quick or target/suite/full)
# --scenes    indices or names, comma-separated (default: all nine), e.g. 0,knot,5
# --seed      seed of the generated scenes (default 1) and of training (train's --seed)
# --train-seed  training seed alone (default: --seed), for telling a setting's effect from seed noise
# --set       passed to `vagsl train` (repeatable), e.g. --set densify.floaters.enabled=true
# --threads   rayon threads per scene (default 2); --jobs: scenes run at once (default 1)
# --backend   rasterizer of train / mesh / eval-images (default: vagsl's auto)
# --remesh    keep each scene's trained OUTDIR/NN-name/run and only mesh and score it again
#             (for trying a meshing rule in minutes: the training columns stay the run's)
# --mesh-arg  passed to the run's `vagsl mesh` (repeatable), e.g. --mesh-arg --smooth --mesh-arg 10
#
# Per scene: the GT-depth floor (`vagsl mesh SCENE --depth-dir SCENE/gt --no-simplify`, the same
# fusion as a run's mesh, unsimplified: simplifying exact depths at the default 0.3 footprint cost
# window's floor 24 % of its Chamfer while the run's mesh lost nothing, so a simplified floor would
# flatter the ratio; scored the same way), then `vagsl train SCENE --eval`, `vagsl mesh RUN`,
# `vagsl eval-mesh --crop-to-gt 0.05 --min-z 0.005` (the object protocol) and
# `vagsl eval-images RUN --json` (the whole image, and `--seen-from SCENE/gt`: the pixels some
# training view sees). Generated scenes are cached under target/suite-scenes; a scene
# whose OUTDIR/NN-name/row.json exists is not run again (delete it to rerun). VAGSL=path picks
# the binary (default target/release/vagsl, built if missing).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
ARGS="$*"
QUICK=0; REMESH=0; MESH_ARGS=(); PRESET=""; OUT=""; SCENES=""; SEED=1; TRAIN_SEED=""; ITERS=""; THREADS=2; JOBS=1; BACKEND=auto; SETS=()
usage() { sed -n '2,24p' "$0" | sed 's/^# \{0,1\}//'; exit "${1:-0}"; }
while [[ $# -gt 0 ]]; do
  case "$1" in
    --quick) QUICK=1 ;;
    --preset) PRESET="$2"; shift ;;
    -o|--output) OUT="$2"; shift ;;
    --scenes) SCENES="$2"; shift ;;
    --seed) SEED="$2"; shift ;;
    --train-seed) TRAIN_SEED="$2"; shift ;;
    --iterations) ITERS="$2"; shift ;;
    --threads) THREADS="$2"; shift ;;
    --jobs) JOBS="$2"; shift ;;
    --backend) BACKEND="$2"; shift ;;
    --set) SETS+=(--set "$2"); shift ;;
    --remesh) REMESH=1 ;;
    --mesh-arg) MESH_ARGS+=("$2"); shift ;;
    -h|--help) usage 0 ;;
    *) echo "suite.sh: unknown argument '$1'" >&2; usage 2 ;;
  esac
  shift
done

MODE=$([[ $QUICK == 1 ]] && echo quick || echo full)
OUT="${OUT:-$ROOT/target/suite/$MODE}"
CACHE="$ROOT/target/suite-scenes/$MODE-seed$SEED"
# What the table says was run: the checkout's commit (taken now, not when the table is
# written), or the binary the caller named.
if [[ -n "${VAGSL:-}" ]]; then BUILT_FROM="the binary $VAGSL"; else BUILT_FROM="at $(git -C "$ROOT" describe --always --dirty 2>/dev/null || echo 'an unknown commit')"; fi
VAGSL="${VAGSL:-$ROOT/target/release/vagsl}"
if [[ ! -x "$VAGSL" ]]; then
  (cd "$ROOT" && cargo build --release -p gs-cli)
fi
export RAYON_NUM_THREADS="$THREADS"
mkdir -p "$OUT" "$CACHE"

# The suite's scene folders (NN-name), written (or kept) by `vagsl synth`.
SYNTH_ARGS=(--seed "$SEED"); [[ $QUICK == 1 ]] && SYNTH_ARGS+=(--quick)
# Scenes chosen by index only: write just those (a full-size scene takes about a minute).
if [[ -n "$SCENES" && "$SCENES" =~ ^[0-9]+(,[0-9]+)*$ ]]; then
  IFS=',' read -ra IDX <<< "$SCENES"
  for i in "${IDX[@]}"; do "$VAGSL" synth -o "$CACHE" --scene "$((10#$i))" "${SYNTH_ARGS[@]}" >&2; done
else
  "$VAGSL" synth -o "$CACHE" --suite "${SYNTH_ARGS[@]}" >&2
fi
mapfile -t ALL < <(cd "$CACHE" && ls -d [0-9][0-9]-* | sort)
SELECTED=()
if [[ -z "$SCENES" ]]; then
  SELECTED=("${ALL[@]}")
else
  IFS=',' read -ra WANT <<< "$SCENES"
  for w in "${WANT[@]}"; do
    hit=""
    for s in "${ALL[@]}"; do
      if [[ "$s" == "$(printf '%02d' "$w" 2>/dev/null)-"* || "${s#*-}" == "$w" || "$s" == "$w" ]]; then hit="$s"; fi
    done
    [[ -n "$hit" ]] || { echo "suite.sh: no suite scene '$w' (have: ${ALL[*]})" >&2; exit 2; }
    SELECTED+=("$hit")
  done
fi

TRAIN_ARGS=(--eval --seed "${TRAIN_SEED:-$SEED}" --backend "$BACKEND")
[[ -n "$PRESET" ]] && TRAIN_ARGS+=(--preset "$PRESET")
[[ -n "$ITERS" ]] && TRAIN_ARGS+=(--iterations "$ITERS")
TRAIN_ARGS+=("${SETS[@]}")
PROTOCOL=(--crop-to-gt 0.05 --min-z 0.005 --json)

LOAD_START="$(cut -d' ' -f1-3 /proc/loadavg)"
T_SUITE=$(date +%s.%N)
run_scene() {
  local s="$1" SCENE="$CACHE/$1" D="$OUT/$1" t0 t1 t2
  echo "== $s" >&2
  if [[ $REMESH == 1 ]]; then
    [[ -f "$D/run/point_cloud.ply" ]] || { echo "suite.sh --remesh: $D/run has no trained model" >&2; return 1; }
    rm -rf "$D/floor"
  else
    rm -rf "$D/run" "$D/floor"
  fi
  mkdir -p "$D/floor"
  t0=$(date +%s.%N)
  "$VAGSL" mesh "$SCENE" --depth-dir "$SCENE/gt" --no-simplify -o "$D/floor/mesh.ply" >&2
  "$VAGSL" eval-mesh --pred "$D/floor/mesh.ply" --gt "$SCENE/gt_mesh.ply" "${PROTOCOL[@]}" > "$D/floor/eval_mesh.json"
  t1=$(date +%s.%N)
  [[ $REMESH == 1 ]] || "$VAGSL" train "$SCENE" -o "$D/run" "${TRAIN_ARGS[@]}" >&2
  "$VAGSL" mesh "$D/run" --backend "$BACKEND" "${MESH_ARGS[@]}" >&2
  "$VAGSL" eval-mesh --pred "$D/run/mesh.ply" --gt "$SCENE/gt_mesh.ply" "${PROTOCOL[@]}" > "$D/eval_mesh.json"
  "$VAGSL" eval-images "$D/run" --json --backend "$BACKEND" > "$D/eval_images.json"
  "$VAGSL" eval-images "$D/run" --json --no-lpips --seen-from "$SCENE/gt" --backend "$BACKEND" > "$D/eval_images_seen.json"
  t2=$(date +%s.%N)
  python3 - "$SCENE" "$D" "$t0" "$t1" "$t2" "$REMESH" <<'PY'
import json, sys
scene, d, (t0, t1, t2), remesh = sys.argv[1], sys.argv[2], map(float, sys.argv[3:6]), sys.argv[6] == "1"
load = lambda p: json.load(open(p))
meta, floor, em = load(f"{scene}/scene.json"), load(f"{d}/floor/eval_mesh.json"), load(f"{d}/eval_mesh.json")
ei, rep, mesh = load(f"{d}/eval_images.json"), load(f"{d}/run/report.json"), load(f"{d}/run/mesh.json")
seen = load(f"{d}/eval_images_seen.json")["views"]
fm, m = floor, em
views = ei["views"]
worst = min(views, key=lambda v: v["psnr"])
worst_seen = min(seen, key=lambda v: v["psnr"])
veils = [v for v in views if v.get("veil")]
row = {
    "scene": d.rstrip("/").split("/")[-1], "views": meta["views"], "texture": meta["texture_strength"]["object"],
    "chamfer": m["chamfer"], "floor_chamfer": fm["chamfer"], "chamfer_ratio": m["chamfer"] / fm["chamfer"],
    "f1": m["f1"], "floor_f1": fm["f1"], "f1_ratio": m["f1"] / fm["f1"], "accuracy": m["accuracy"], "completeness": m["completeness"],
    "psnr": ei["psnr"], "worst_view": worst["name"], "worst_psnr": worst["psnr"],
    "worst_seen_view": worst_seen["name"], "worst_seen_psnr": worst_seen["psnr"], "worst_seen_share": worst_seen["mask_fraction"],
    "veils": len(veils), "veil_views": [f'{v["name"]} ({v["veil"]["psnr_without"]:.1f} dB without)' for v in veils],
    "triangles": mesh["triangles"], "gaussians": rep["gaussians"], "train_seconds": rep["train_seconds"],
    # --remesh: the run's own training time plus this mesh and its scoring.
    "total_seconds": t2 - t1 + (rep["train_seconds"] if remesh else 0.0), "floor_seconds": t1 - t0,
}
json.dump(row, open(f"{d}/row.json", "w"), indent=1)
PY
}
for s in "${SELECTED[@]}"; do
  if [[ $REMESH == 1 ]]; then rm -f "$OUT/$s/row.json"; fi
  if [[ -f "$OUT/$s/row.json" ]]; then echo "== $s: kept $OUT/$s/row.json" >&2; continue; fi
  if [[ $JOBS -gt 1 ]]; then
    mkdir -p "$OUT/$s"
    ( set -e; run_scene "$s" > "$OUT/$s/log.txt" 2>&1 ) &
    while [[ $(jobs -rp | wc -l) -ge $JOBS ]]; do wait -n || true; done
  else
    set +e; ( set -e; run_scene "$s" ); set -e
  fi
done
wait || true
DONE=()
for s in "${SELECTED[@]}"; do
  if [[ -f "$OUT/$s/row.json" ]]; then DONE+=("$s"); else echo "suite.sh: $s failed (see $OUT/$s/log.txt or the output above)" >&2; fi
done
[[ ${#DONE[@]} -gt 0 ]] || exit 1
T_END=$(date +%s.%N)

# The table: one row per scene, then the mean and the worst value of every column.
SUITE_BUILT_FROM="$BUILT_FROM" python3 - "$OUT" "$MODE" "$SEED" "$PRESET" "$THREADS" "$LOAD_START" "$(cut -d' ' -f1-3 /proc/loadavg)" \
  "$(python3 -c "print($T_END - $T_SUITE)")" "$ARGS" "${DONE[@]}" <<'PY'
import json, sys, os
out, mode, seed, preset, threads, load0, load1, wall, _args, *scenes = sys.argv[1:]
rows = [json.load(open(f"{out}/{s}/row.json")) for s in scenes]
built_from = os.environ["SUITE_BUILT_FROM"]
cols = [  # header, key, format, worst = max or min
    ("Chamfer", "chamfer", "{:.5f}", max), ("floor", "floor_chamfer", "{:.5f}", max), ("× floor", "chamfer_ratio", "{:.2f}", max),
    ("F1", "f1", "{:.3f}", min), ("floor F1", "floor_f1", "{:.3f}", min), ("F1 ÷ floor", "f1_ratio", "{:.3f}", min),
    ("PSNR", "psnr", "{:.2f}", min), ("worst view", "worst_psnr", "{:.2f}", min), ("worst seen", "worst_seen_psnr", "{:.2f}", min),
    ("veils", "veils", "{:d}", max),
    ("triangles", "triangles", "{:,}", max), ("Gaussians", "gaussians", "{:,}", max),
    ("train s", "train_seconds", "{:.0f}", max), ("total s", "total_seconds", "{:.0f}", max),
]
fmt = lambda f, v: f.format(int(round(v)) if f in ("{:d}", "{:,}") else v)
lines = [
    f"# Validation suite ({mode}, seed {seed}, preset {preset or 'default'})", "",
    f"`scripts/suite.sh {_args}`".replace("` ", "`").replace(" `", "`") + f" {built_from}; {threads} thread{'' if threads == '1' else 's'} "
    f"(RAYON_NUM_THREADS); load average {load0} at the start, {load1} at the end; {float(wall) / 60:.1f} min of wall time "
    "for the scenes run now. Object protocol: crop to the object's box + 5 %, floor (z < 0.005) removed, "
    "τ = 0.5 % of its diagonal; the floor is `vagsl mesh SCENE --depth-dir SCENE/gt --no-simplify` scored the same way. "
    "PSNR: held-out views (every 8th); worst view = its lowest PSNR; worst seen = the lowest PSNR over the pixels "
    "some training view sees (`eval-images --seen-from SCENE/gt`), with that share of the view; veils = held-out views where "
    "`eval-images` names a veil. Times: train = the training loop; total = train + mesh + both evals.", "",
    "| scene | views | texture | " + " | ".join(c[0] for c in cols) + " |",
    "|---|---|---|" + "---|" * len(cols),
]
for r in rows:
    cells = [fmt(f, r[k]) for _, k, f, _ in cols]
    cells[7] = f'{r["worst_view"]} {r["worst_psnr"]:.2f}'
    cells[8] = f'{r["worst_seen_view"]} {r["worst_seen_psnr"]:.2f} ({100 * r["worst_seen_share"]:.0f} %)'
    lines.append(f'| {r["scene"]} | {r["views"]} | {r["texture"]:.2f} | ' + " | ".join(cells) + " |")
mean = [fmt(f.replace(":d", ":.1f").replace(":,", ":,.0f"), sum(r[k] for r in rows) / len(rows)) for _, k, f, _ in cols]
lines.append("| **mean** | | | " + " | ".join(mean) + " |")
worst = [fmt(f, w(r[k] for r in rows)) for _, k, f, w in cols]
lines.append("| **worst** | | | " + " | ".join(worst) + " |")
veiled = [f'{r["scene"]}: {", ".join(r["veil_views"])}' for r in rows if r["veils"]]
if veiled:
    lines += ["", "Veils: " + "; ".join(veiled) + "."]
open(f"{out}/suite.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
