# shellcheck shell=bash
# Sourced by run.sh and blind.sh: `ensure_venv PKG VER` creates (once) the venv that holds wheel PKG==VER and sets
# `venv`, `adapter` (the adapters/python script of the engine) and `label`. Uses REDISCOVERY_VENVS (default
# $CARGO_TARGET_DIR/venvs), REDISCOVERY_VENV_PREFIX (default empty) and the caller's `nice_cmd` array.
ensure_venv() {
    local pkg="$1" ver="$2" numpy t0
    venv="${REDISCOVERY_VENVS:-$CARGO_TARGET_DIR/venvs}/${REDISCOVERY_VENV_PREFIX:-}$pkg-$ver"
    case "$pkg" in
        mujoco) adapter=scenes_mujoco.py label="MuJoCo $ver" numpy="numpy<2.3" ;;
        pybullet) adapter=scenes_pybullet.py label="pybullet $ver" numpy="numpy<2" ;;
        dartpy) adapter=scenes_dart.py label="dartpy $ver" numpy="numpy<2.3" ;;
        *) echo "unknown wheel $pkg" >&2; return 1 ;;
    esac
    if ! "$venv/bin/python" -c "import importlib.metadata as m, sys; sys.exit(m.version('$pkg') != '$ver')" 2>/dev/null; then
        t0=$(date +%s)
        python3 -m venv "$venv"
        "${nice_cmd[@]}" "$venv/bin/pip" install --quiet "$pkg==$ver" "$numpy"
        echo "$label: venv $(( $(date +%s) - t0 )) s" >&2
    fi
}
