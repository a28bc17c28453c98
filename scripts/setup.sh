#!/usr/bin/env bash
# Installs everything a fresh machine needs beyond the Rust toolchain, gcc and Python 3.11: cargo-nextest,
# Debian packages (cmake, make, g++, libclang for cyclors' bindgen, Cyclone DDS 0.10.2 for the interop peers,
# DART 6.12 with its URDF loader and ODE collision detector for the `dart` engine),
# a Python venv with the oracle packages and a static ffmpeg (imageio-ffmpeg, for the videos), and the MuJoCo shared library from the PyPI wheel.
# Idempotent: a second run only checks.
#   scripts/setup.sh          what building, `scripts/test.sh` (CI) and `scripts/run.sh` need
#   scripts/setup.sh --fuzz   the same, plus cargo-fuzz from crates.io for `cargo +nightly fuzz run TARGET` (kept out
#                             of the default: its build costs CI minutes, and CI fuzzes on stable with scripts/fuzz.sh)
#   scripts/setup.sh --newton the same, plus Newton 1.8.0 (NVIDIA Warp, ~575 MB with warp-lang and numpy) in its own
#                             venv .venv-newton ($ULAB_NEWTON_VENV), for the `newton_*` engines of
#                             `cargo build -p ulab --features newton`: the main venv's pinned numpy and mujoco stay
#                             untouched. CI neither installs nor builds Newton.
#   scripts/setup.sh --ray    the same, plus Ray 2.x (~285 MB) in its own venv .venv-ray ($ULAB_RAY_VENV), for
#                             multi-machine campaigns (scripts/campaign.py, docs/campaigns.md); not in CI.
set -euo pipefail
cd "$(dirname "$0")/.."
FUZZ=0
NEWTON=0
RAY=0
for arg in "$@"; do
  case "$arg" in
    --fuzz) FUZZ=1 ;;
    --newton) NEWTON=1 ;;
    --ray) RAY=1 ;;
    *) echo "usage: $0 [--fuzz] [--newton] [--ray]" >&2; exit 2 ;;
  esac
done
source scripts/env.sh

APT_PACKAGES=(cmake make g++ libclang-dev clang pkg-config cyclonedds-dev cyclonedds-tools
  libbullet-dev  # Bullet 3.24 with the double-precision build (bullet-float64.pc): the `bullet` engine
  libdart-dev libdart-utils-urdf-dev libdart-collision-ode-dev)  # DART 6.12: the `dart` engine
missing=()
for p in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

# cargo-nextest, the test runner of scripts/test.sh: from crates.io when the machine lacks it (a few minutes' build).
if ! cargo nextest --version >/dev/null 2>&1; then
  echo "setup: installing cargo-nextest from crates.io"
  cargo install --locked --quiet cargo-nextest --version 0.9.143 --no-default-features --features default-no-update
fi

# cargo-fuzz (--fuzz only). Its address-sanitizer build needs a nightly toolchain, which rustup installs; without one
# the stable path stays: scripts/fuzz.sh.
if [ "$FUZZ" = 1 ]; then
  if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "setup: installing cargo-fuzz from crates.io"
    cargo install --locked --quiet cargo-fuzz --version 0.13.2
  fi
  if ! cargo +nightly --version >/dev/null 2>&1; then
    echo "setup: installing the nightly toolchain (cargo fuzz's address sanitizer needs it)"
    rustup toolchain install nightly --profile minimal \
      || echo "setup: no nightly toolchain; fuzz on stable with scripts/fuzz.sh (no address sanitizer)" >&2
  fi
fi

if [ ! -x "$ULAB_PYTHON" ]; then
  echo "setup: creating Python venv in .venv"
  python3 -m venv "$ULAB_VENV"
fi
if ! "$ULAB_PYTHON" -c "import importlib.util as u, mujoco, cyclonedds, mcap, numpy, onnxruntime, imageio_ffmpeg; assert u.find_spec('unitree_sdk2py')" 2>/dev/null; then
  echo "setup: installing Python packages"
  "$ULAB_PYTHON" -m pip install -q --disable-pip-version-check -r scripts/requirements.txt
  # The SDK's own dependency list pins an old cyclonedds; we bring a known one above.
  "$ULAB_PYTHON" -m pip install -q --disable-pip-version-check --no-deps unitree_sdk2==1.0.1
fi

# A package in a venv of its own, whose dependencies must not move the main venv's pins: creates VENV if missing,
# installs PACKAGE==VERSION unless that version is there.   own_venv LABEL VENV PYTHON PACKAGE VERSION SIZE
own_venv() {
  local label=$1 venv=$2 py=$3 pkg=$4 version=$5 size=$6
  if [ ! -x "$py" ]; then
    echo "setup: creating the $label venv in $venv"
    python3 -m venv "$venv"
  fi
  if ! "$py" -c "import importlib.metadata as m, sys; sys.exit(m.version('$pkg') != '$version')" 2>/dev/null; then
    echo "setup: installing $pkg==$version ($size)"
    "$py" -m pip install -q --disable-pip-version-check "$pkg==$version"
  fi
}
# Newton (--newton only): its numpy (2.x) and Warp. Ray (--ray only): its protobuf and grpc.
[ "$NEWTON" = 0 ] || own_venv Newton "$ULAB_NEWTON_VENV" "$ULAB_NEWTON_PYTHON" newton 1.8.0 "with warp-lang and numpy, ~575 MB"
[ "$RAY" = 0 ] || own_venv Ray "$ULAB_RAY_VENV" "$ULAB_RAY_PYTHON" ray 2.60.0 "~285 MB"

mkdir -p "$MUJOCO_DYNAMIC_LINK_DIR"
lib=$("$ULAB_PYTHON" -c "import mujoco, os, glob; print(sorted(glob.glob(os.path.join(os.path.dirname(mujoco.__file__), 'libmujoco.so.*')))[-1])")
ln -sf "$lib" "$MUJOCO_DYNAMIC_LINK_DIR/libmujoco.so"
ln -sf "$lib" "$MUJOCO_DYNAMIC_LINK_DIR/$(basename "$lib")"
echo "setup: ok (MuJoCo: $lib)"
[ "$NEWTON" = 0 ] || echo "setup: Newton: $("$ULAB_NEWTON_PYTHON" -c 'import importlib.metadata as m; print(m.version("newton"))') in $ULAB_NEWTON_VENV"
[ "$RAY" = 0 ] || echo "setup: Ray: $("$ULAB_RAY_PYTHON" -c 'import ray; print(ray.__version__)') in $ULAB_RAY_VENV"
[ "$FUZZ" = 0 ] || echo "setup: fuzzing: $(cargo fuzz --version), $(cargo +nightly --version 2>/dev/null || echo no nightly)"
