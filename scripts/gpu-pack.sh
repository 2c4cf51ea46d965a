#!/usr/bin/env bash
# Packs what scripts/gpu-check.sh needs on a GPU machine that reaches no registry: stripped
# release binaries (vagsl, the rasterizer bench, the wgpu parity tests of the rasterizer, L_p,
# L_f, L_I, L_nc/L_ns, the resident model's Adam, density control and gs-gpu's scan, sort and
# sums) in one solid xz archive, the synth-bunny scene without its GT depth maps, and the Vulkan
# loader's Debian packages. Run it here, in the repository root; it fills the ignored folders .gpu/ and .gl/, which travel with `carry`.
#
#   scripts/gpu-pack.sh [--baseline PATH_TO_OLD_VAGSL] [--baseline-bench OLD_RASTER_BENCH NAME]
#
# --baseline also packs an older vagsl binary (vagsl-baseline in the archive): gpu-check then runs
# the README job with it beside the new one on the same machine. --baseline-bench packs an
# older raster bench (plain or .gz, built from commit NAME): gpu-check runs its wgpu rows
# right after the new ones, so a speed-up is a ratio measured on one machine.
set -euo pipefail
cd "$(dirname "$0")/.."
baseline=""; bench_base=""; bench_name=""
while [ $# -gt 0 ]; do
  case "$1" in
    --baseline) baseline="$2"; shift 2 ;;
    --baseline-bench) bench_base="$2"; bench_name="$3"; shift 3 ;;
    *) echo "gpu-pack: unknown argument $1" >&2; exit 2 ;;
  esac
done
data="${VAGSL_TEST_DATA:-../shared}/data/synth-bunny"
[ -d "$data/images" ] || { echo "gpu-pack: synth-bunny not found at $data (set VAGSL_TEST_DATA)" >&2; exit 1; }

for p in /.gpu/ /.gl/; do grep -qxF "$p" .git/info/exclude 2>/dev/null || echo "$p" >> .git/info/exclude; done
rm -rf .gpu && mkdir -p .gpu/bin .gpu/data

# Binaries: cargo prints each test/bench executable's path as JSON; take the last of each name.
# Built with --workspace, so the features are those `cargo test --workspace --release` builds
# with (a -p build unifies other features and recompiles half the workspace).
cargo build --release --workspace --bins
exe() { cargo "$@" --workspace --message-format=json 2>/dev/null \
  | python3 -c 'import sys,json
p=[m["executable"] for m in map(json.loads,sys.stdin) if m.get("reason")=="compiler-artifact" and m.get("executable")]
print(p[-1])'; }
raster=$(exe bench --bench raster --no-run)
parity=$(exe test --release --test wgpu_parity --no-run)
lp_parity=$(exe test --release --test photometric_gpu --no-run)
lf_parity=$(exe test --release --test feature_gpu --no-run)
image_parity=$(exe test --release --test image_gpu --no-run)
normal_parity=$(exe test --release --test normal_gpu --no-run)
resident_parity=$(exe test --release --test wgpu_resident --no-run)
guess_parity=$(exe test --release --test wgpu_guessed_render --no-run)
vgg_parity=$(exe test --release --test vgg_gpu --no-run)
split_parity=$(exe test --release --test wgpu_tile_split --no-run)
densify_parity=$(exe test --release --test wgpu_densify --no-run)
sums_parity=$(exe test --release --test device --no-run)
strip -o .gpu/bin/vagsl target/release/vagsl
strip -o .gpu/bin/raster-bench "$raster"
strip -o .gpu/bin/wgpu-parity "$parity"
strip -o .gpu/bin/lp-parity "$lp_parity"
strip -o .gpu/bin/lf-parity "$lf_parity"
strip -o .gpu/bin/image-parity "$image_parity"
strip -o .gpu/bin/normal-parity "$normal_parity"
strip -o .gpu/bin/resident-parity "$resident_parity"
strip -o .gpu/bin/guess-parity "$guess_parity"
strip -o .gpu/bin/vgg-parity "$vgg_parity"
strip -o .gpu/bin/split-parity "$split_parity"
strip -o .gpu/bin/densify-parity "$densify_parity"
strip -o .gpu/bin/sums-parity "$sums_parity"
[ -n "$baseline" ] && strip -o .gpu/bin/vagsl-baseline "$baseline"
if [ -n "$bench_base" ]; then
  case "$bench_base" in *.gz) gunzip -c "$bench_base" > .gpu/bin/raster-bench-baseline ;; *) strip -o .gpu/bin/raster-bench-baseline "$bench_base" ;; esac
  echo "$bench_name" > .gpu/baseline
fi
# The tree that travels (tracked files, .gpu, .gl) is capped at 64 MiB. The binaries share most
# of their code (wgpu, naga, the crates), which one solid archive stores once: 93 MB stripped,
# 41 MB gzipped one by one, 16 MB as one xz archive (stop 69).
tar -C .gpu/bin -cf - . | xz -9e -T2 > .gpu/bin.tar.xz
rm -rf .gpu/bin
git rev-parse --short HEAD > .gpu/commit
git status --porcelain --untracked-files=no | grep -q . && echo "+uncommitted" >> .gpu/commit

# synth-bunny without gt/ (27 MB of depth maps the check does not read).
mkdir -p .gpu/data/synth-bunny
cp -r "$data/images" "$data/sparse" "$data/masks" "$data/gt_mesh.ply" .gpu/data/synth-bunny/

# The Vulkan loader (the device machine has the NVIDIA driver but no loader).
if ! ls .gl/libvulkan1_*.deb >/dev/null 2>&1; then
  mkdir -p .gl /tmp/amd64/partial
  o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
  apt-get $o update -qq
  (cd .gl && apt-get $o download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
fi
du -sh .gpu .gl
echo "gpu-pack: ready; run on the device: bash scripts/gpu-check.sh (carry .gpu and .gl)"
