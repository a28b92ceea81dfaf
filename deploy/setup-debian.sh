#!/usr/bin/env bash
# Installs what Reenact needs on Debian 12: the Debian packages it builds
# against and the npm packages its tests use as independent checkers.
# Idempotent: installs only what is missing. Runs as root or through sudo.
set -euo pipefail
cd "$(dirname "$0")/.."

if [ "$(id -u)" -eq 0 ]; then
  SUDO=()
elif command -v sudo >/dev/null 2>&1; then
  SUDO=(sudo)
else
  echo "setup-debian: run as root or install sudo" >&2
  exit 1
fi

packages=(
  build-essential cmake ninja-build pkg-config git ccache
  clang libclang-rt-14-dev clang-format clang-tidy
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  libabsl-dev libeigen3-dev libboost-dev libceres-dev libpcl-dev libopencv-dev
  libusb-1.0-0-dev libfreenect-dev libopenni2-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libsqlite3-dev libzstd-dev zlib1g-dev libturbojpeg0-dev libpng-dev
  libegl-dev libopengl-dev libgl1-mesa-dri libglfw3-dev
  libtinygltf-dev nlohmann-json3-dev libspdlog-dev
  libavformat-dev libavcodec-dev libswscale-dev
  xvfb xauth
  chromium
  python3-yaml  # tests/deploy/check_kubernetes.py reads the Kubernetes manifests
  slurm-wlm munge  # the scale-out tests run a one-node Slurm cluster (deploy/slurm)
)
# Node.js may come from elsewhere (with npm bundled); only add Debian's when
# there is none.
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  packages+=(nodejs npm)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup-debian: installing ${#missing[@]} packages: ${missing[*]}"
  "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
else
  echo "setup-debian: Debian packages already installed"
fi

# npm checkers used by the tests (an independent MCAP reader, glTF validator).
if [ -f tests/js/package.json ]; then
  if [ ! -d tests/js/node_modules ] || [ tests/js/package.json -nt tests/js/node_modules ]; then
    echo "setup-debian: installing npm test checkers into tests/js/node_modules"
    npm install --prefix tests/js --no-audit --no-fund --loglevel=error
    touch tests/js/node_modules
  else
    echo "setup-debian: npm test checkers already installed"
  fi
fi

# The tablet web app's build tools and libraries (three, esbuild) and its
# browser tests' driver (playwright-core, which drives Debian's chromium),
# exactly as its lockfile says.
if [ -f clients/web/package-lock.json ]; then
  if [ ! -d clients/web/node_modules ] || [ clients/web/package-lock.json -nt clients/web/node_modules ]; then
    echo "setup-debian: installing the web app's npm packages into clients/web/node_modules"
    npm ci --prefix clients/web --no-audit --no-fund --loglevel=error
    touch clients/web/node_modules
  else
    echo "setup-debian: the web app's npm packages already installed"
  fi
fi
