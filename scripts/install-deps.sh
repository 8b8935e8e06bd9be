#!/usr/bin/env bash
# Installs what strata needs on a Debian 12 machine: build tools and libraries from apt.
# Idempotent: packages already installed are skipped; a failure names the package.
#   bash scripts/install-deps.sh [--tests]
#     --tests  also what only the test suite needs: Debian's chromium (the viewer's browser tests)
set -euo pipefail

apt_packages=(
    g++ cmake make pkg-config git ccache
    libopenimageio-dev openimageio-tools libopencv-core-dev  # image stacks (see PACKAGES.md)
    zlib1g-dev                                               # NIfTI .nii.gz, NRRD gzip
    libdcmtk-dev                                             # DICOM RTSTRUCT (DCMTK dcmdata)
    libtiff-dev                                              # TIFF strips checked (input)
    nlohmann-json3-dev libcli11-dev
    libtinygltf-dev libdraco-dev                             # glTF writer, Draco chunks
    libmeshoptimizer-dev                                     # EXT_meshopt_compression (lods.glb)
    libcgal-dev libgmp-dev libmpfr-dev                       # exact geometry (self-intersection)
    libgtest-dev libgmock-dev libbenchmark-dev               # tests and benchmarks
    clang-format-14                                          # formatting check
    nodejs npm                                               # glTF validator (tests/node)
)
if [ "${1:-}" = "--tests" ]; then
    apt_packages+=(chromium)                                 # web-viewer browser tests
fi

missing=()
for p in "${apt_packages[@]}"; do
    # note: a node that bundles npm (NodeSource's nodejs) is enough; Debian's npm conflicts
    # with it, and asking apt for npm would replace that node.
    if [[ "$p" == nodejs || "$p" == npm ]] && command -v node >/dev/null &&
        command -v npm >/dev/null; then
        continue
    fi
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing+=("$p")
    fi
done

if [ "${#missing[@]}" -eq 0 ]; then
    echo "install-deps: all ${#apt_packages[@]} Debian packages present"
    exit 0
fi

echo "install-deps: installing ${missing[*]}"
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
    sudo_cmd=(sudo)
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -q >/dev/null || {
    echo "install-deps: error: apt-get update failed" >&2
    exit 1
}
if ! "${sudo_cmd[@]}" apt-get install -y -q "${missing[@]}" >/tmp/strata-apt.log 2>&1; then
    echo "install-deps: error: apt-get install failed; packages one by one:" >&2
    for p in "${missing[@]}"; do
        "${sudo_cmd[@]}" apt-get install -y -q "$p" >/dev/null 2>&1 ||
            echo "install-deps: error: cannot install Debian package '$p'" >&2
    done
    exit 1
fi
echo "install-deps: done"
