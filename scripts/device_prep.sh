#!/bin/bash
# Prepare a lent-GPU session (run here, in the project's root, before asking
# for the device, so no device time goes to building): the steps of
# scripts/gpu/README.md (vendored from the project's shared/gpu/) in one go,
# plus scripts/gpu_tune.sh. Everything it copies is in this repository.
#   .gl/   the Vulkan loader and friends as .deb files (unpacked on the device)
#   .gpu/  a stripped release `cradle` and `chain_contract`, bench.sh, compare.py, gpu_tune.sh,
#          grid100/grid1000 and stress.toml, the numba.cuda peer
# Both folders are git-excluded. Then, with the device tool, one call carrying
# .gl and .gpu: `bash .gpu/gpu_check.sh` (the one call of issue #48: about 6
# minutes; its table and logs come back in $OUT). The older, longer scripts:
#   for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig; bash .gpu/bench.sh; bash .gpu/gpu_tune.sh
# and, for the GPU peer: python3 .gpu/numba_cuda_grid.py --nf 1000 --ng 1000 --dt-div 10000
set -euo pipefail
cd "$(dirname "$0")/.."
exclude=$(git rev-parse --git-path info/exclude)
mkdir -p "$(dirname "$exclude")"
for d in .gl .gpu; do
  grep -qx "/$d/" "$exclude" 2>/dev/null || echo "/$d/" >> "$exclude"
done
mkdir -p .gl .gpu /tmp/amd64/partial
if ! ls .gl/libvulkan1_*.deb >/dev/null 2>&1; then
  o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
  apt-get $o update -qq
  (cd .gl && apt-get $o download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2)
fi
cargo build --release
cargo build --release --example chain_contract
cp target/release/cradle .gpu/ && strip .gpu/cradle
# What the binary was built from (gpu_check.sh prints it).
{ git rev-parse --short HEAD; [ -z "$(git status --porcelain --untracked-files=no)" ] || echo "+ uncommitted changes"; } | paste -sd' ' > .gpu/COMMIT
cp target/release/examples/chain_contract .gpu/ && strip .gpu/chain_contract
cp scripts/gpu/bench.sh scripts/gpu/compare.py examples/stress.toml scripts/gpu_tune.sh scripts/gpu_check.sh .gpu/
cp scripts/peers/numba_cuda_grid.py .gpu/
python3 scripts/grid.py 1000 1000 > .gpu/grid1000.toml
python3 scripts/grid.py 100 100 > .gpu/grid100.toml
du -sh .gl .gpu
echo "ready: carry [.gl, .gpu] (under the 64 MiB limit together)"
