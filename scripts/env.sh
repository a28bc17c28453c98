# Source this: environment for building and testing ulab on this checkout.
# Paths are relative to the repository root so a clean clone works anywhere.
ULAB_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export ULAB_ROOT
export ULAB_VENV="$ULAB_ROOT/.venv"
export ULAB_PYTHON="$ULAB_VENV/bin/python"
# Newton's own venv (`scripts/setup.sh --newton`); the `newton_*` engines start $ULAB_NEWTON_PYTHON.
export ULAB_NEWTON_VENV="${ULAB_NEWTON_VENV:-$ULAB_ROOT/.venv-newton}"
export ULAB_NEWTON_PYTHON="${ULAB_NEWTON_PYTHON:-$ULAB_NEWTON_VENV/bin/python}"
# Ray's own venv (`scripts/setup.sh --ray`): scripts/campaign.py runs on $ULAB_RAY_PYTHON.
export ULAB_RAY_VENV="${ULAB_RAY_VENV:-$ULAB_ROOT/.venv-ray}"
export ULAB_RAY_PYTHON="${ULAB_RAY_PYTHON:-$ULAB_RAY_VENV/bin/python}"
# mujoco-rs links libmujoco.so dynamically; the library comes from the PyPI wheel (see setup.sh).
export MUJOCO_DYNAMIC_LINK_DIR="$ULAB_ROOT/.deps/mujoco"
export LD_LIBRARY_PATH="$MUJOCO_DYNAMIC_LINK_DIR${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
# Reference material lives beside the checkout, never inside it.
export ULAB_SHARED="${ULAB_SHARED:-$(cd "$ULAB_ROOT/../shared" 2>/dev/null && pwd)}"
