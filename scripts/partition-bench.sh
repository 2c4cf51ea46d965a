#!/usr/bin/env bash
# Partitioned against single-machine training on the same scene (BENCHMARKS.md §Partitioned
# training): one run of the whole scene on T threads, then `vagsl partition --blocks N` with its
# N blocks trained at once (each on T/N threads, as N workers of one machine would), merged;
# both meshed and scored the same way. Writes OUT/partition.md and OUT/partition.json.
#
#   scripts/partition-bench.sh SCENE [-o OUT] [--blocks N] [--threads T] [--machines]
#                              [-p PARTITION_OPTION]... [-- TRAIN_ARGS...]
#
# SCENE    a scene folder with gt_mesh.ply (e.g. `vagsl synth --street --quick -o DIR`)
# -o OUT   where the runs and the table go (default target/partition-bench)
# --blocks N (default 2); --threads T (default 2): the single run's threads, split among blocks
# --machines: N machines like the single run's instead: each block alone on T threads, one after
#   another; the partitioned wall time counts the slowest block (blocks share nothing)
# -p OPTION  an option for `vagsl partition` (repeat for several words), e.g. -p --grow-everywhere
# after -- options for every `vagsl train` (single run and blocks), e.g. -- --preset fast
# VAGSL=path picks the binary (default target/release/vagsl).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SCENE=""; OUT="$ROOT/target/partition-bench"; N=2; T=2; EXTRA=(); MACHINES=0; PARGS=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    -o) OUT="$2"; shift ;;
    --blocks) N="$2"; shift ;;
    --threads) T="$2"; shift ;;
    --machines) MACHINES=1 ;;
    -p) PARGS+=("$2"); shift ;;
    --) shift; EXTRA=("$@"); break ;;
    -h|--help) sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) [[ -z "$SCENE" ]] || { echo "partition-bench.sh: unexpected '$1'" >&2; exit 2; }; SCENE="$1" ;;
  esac
  shift
done
[[ -n "$SCENE" && -f "$SCENE/gt_mesh.ply" ]] || { echo "partition-bench.sh: give a scene folder with gt_mesh.ply" >&2; exit 2; }
VAGSL="${VAGSL:-$ROOT/target/release/vagsl}"
PER=$(( T / N > 0 ? T / N : 1 ))
(( MACHINES )) && PER=$T
PROTOCOL=(--crop-to-gt 0.05 --min-z 0.005 --json)
rm -rf "$OUT"; mkdir -p "$OUT"
now() { date +%s.%N; }
score() { # RUN: mesh, eval-mesh, eval-images
  "$VAGSL" mesh "$1" --backend cpu >&2
  "$VAGSL" eval-mesh --pred "$1/mesh.ply" --gt "$SCENE/gt_mesh.ply" "${PROTOCOL[@]}" > "$1/../$(basename "$1")-mesh.json"
  "$VAGSL" eval-images "$1" --json --backend cpu > "$1/../$(basename "$1")-images.json"
}

echo "== single run, $T threads" >&2
t0=$(now)
RAYON_NUM_THREADS=$T /usr/bin/time -f "%M" -o "$OUT/single-rss" "$VAGSL" train "$SCENE" -o "$OUT/single" --eval --backend cpu --quiet "${EXTRA[@]}" >&2
t1=$(now)
RAYON_NUM_THREADS=$T score "$OUT/single"

echo "== partition into $N blocks on $PER thread(s) each ($( ((MACHINES)) && echo "one at a time, as $N machines" || echo "at once" ))" >&2
t2=$(now)
"$VAGSL" partition "$SCENE" -o "$OUT/plan" --blocks "$N" --eval --cpus-per-job "$PER" "${PARGS[@]}" -- --backend cpu "${EXTRA[@]}" >&2
t3=$(now)
block() { # INDEX: train one block, its elapsed seconds into OUT/block-INDEX-s
  local b0; b0=$(now)
  RAYON_NUM_THREADS=$PER VAGSL="$VAGSL" /usr/bin/time -f "%M" -o "$OUT/block-$1-rss" bash "$OUT/plan/run-block.sh" "$1" > "$OUT/block-$1.log" 2>&1
  awk -v a="$b0" -v b="$(now)" 'BEGIN { print b - a }' > "$OUT/block-$1-s"
}
for i in $(seq 0 $((N - 1))); do
  if (( MACHINES )); then block "$i"; else block "$i" & fi
done
wait
t4=$(now)
"$VAGSL" merge "$OUT/plan" -o "$OUT/merged" >&2
t5=$(now)
RAYON_NUM_THREADS=$T score "$OUT/merged"

python3 - "$OUT" "$N" "$T" "$PER" "$t0" "$t1" "$t2" "$t3" "$t4" "$t5" "$*" "$MACHINES" <<'PY'
import json, sys, subprocess
out, n, t, per = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
t0, t1, t2, t3, t4, t5 = map(float, sys.argv[5:11])
machines = sys.argv[12] == "1"
load = lambda p: json.load(open(p))
kib = lambda p: int(open(p).read().split()[-1])
s_mesh, s_img, m_mesh, m_img = (load(f"{out}/{r}-{k}.json") for r in ("single", "merged") for k in ("mesh", "images"))
s_rep, m_rep, plan = load(f"{out}/single/report.json"), load(f"{out}/merged/report.json"), load(f"{out}/plan/plan.json")
single_rss = kib(f"{out}/single-rss")
blocks = [{"index": b["index"], "views": len(b["views"]), "iterations": b["train"]["iterations"], "estimate_mib": b["memory_bytes"] / 2**20,
           "peak_mib": kib(f"{out}/block-{b['index']}-rss") / 1024, "train_s": m_rep["blocks"][b["index"]]["train_seconds"],
           "trained": m_rep["blocks"][b["index"]]["gaussians_trained"], "kept": m_rep["blocks"][b["index"]]["gaussians_kept"],
           "wall_s": float(open(f"{out}/block-{b['index']}-s").read())} for b in plan["blocks"]]
views = load(f"{out}/single/config.json")["train_views"]
# N machines at once (--machines): the blocks ran one after another, the slowest bounds the wall.
blocks_wall = max(b["wall_s"] for b in blocks) if machines else t4 - t3
row = {"blocks": n, "threads": t, "threads_per_block": per, "machines": machines,
       "single": {"wall_s": t1 - t0, "psnr": s_img["psnr"], "chamfer": s_mesh["chamfer"], "f1": s_mesh["f1"], "peak_mib": single_rss / 1024, "gaussians": s_rep["gaussians"], "train_views": len(views)},
       "partitioned": {"partition_s": t3 - t2, "blocks_wall_s": blocks_wall, "merge_s": t5 - t4, "wall_s": (t3 - t2) + blocks_wall + (t5 - t4), "psnr": m_img["psnr"], "chamfer": m_mesh["chamfer"], "f1": m_mesh["f1"], "gaussians": m_rep["gaussians"]},
       "per_block": blocks}
json.dump(row, open(f"{out}/partition.json", "w"), indent=1)
commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
s, p = row["single"], row["partitioned"]
how = f"{n} blocks one at a time on {per} thread(s) each, as {n} machines (wall: the slowest block)" if machines else f"{n} blocks at once on {per} thread(s) each"
lines = [f"`scripts/partition-bench.sh {sys.argv[11]}` at {commit}; single run on {t} threads, {how}.", "",
         "| run | wall s | held-out PSNR | Chamfer | F1 | Gaussians | peak memory |", "|---|---|---|---|---|---|---|",
         f"| single | {s['wall_s']:.0f} | {s['psnr']:.2f} | {s['chamfer']:.5f} | {s['f1']:.3f} | {s['gaussians']:,} | {s['peak_mib']:.0f} MiB |",
         f"| {n} blocks (partition {p['partition_s']:.1f} s + blocks {p['blocks_wall_s']:.0f} s + merge {p['merge_s']:.1f} s) | {p['wall_s']:.0f} | {p['psnr']:.2f} | {p['chamfer']:.5f} | {p['f1']:.3f} | {p['gaussians']:,} | {max(b['peak_mib'] for b in blocks):.0f} MiB (largest block) |",
         "", f"Ratios: wall {p['wall_s'] / s['wall_s']:.2f} (target ≤ {1.3 / n:.2f} + merge), PSNR {p['psnr'] - s['psnr']:+.2f} dB (target ≥ −0.5), Chamfer {p['chamfer'] / s['chamfer']:.2f}× (target ≤ 1.10), largest block peak {max(b['peak_mib'] for b in blocks) / s['peak_mib']:.2f} of the single run's.", "",
         "| block | views | iterations | estimate | peak | train s | Gaussians trained | kept |", "|---|---|---|---|---|---|---|---|"]
lines += [f"| {b['index']:02d} | {b['views']} of {s['train_views']} | {b['iterations']} | {b['estimate_mib']:.0f} MiB | {b['peak_mib']:.0f} MiB | {b['train_s']:.0f} | {b['trained']:,} | {b['kept']:,} |" for b in blocks]
open(f"{out}/partition.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
