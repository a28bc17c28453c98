#!/usr/bin/env bash
# A Python venv on Cyclone DDS 0.10.2, the DDS the robots run and the version unitree_sdk2_python's setup.py pins:
# PyPI's `cyclonedds==0.10.2` is a source package only, built here against Debian's libddsc 0.10.2 (`cyclonedds-dev`,
# which scripts/setup.sh installs), with numpy for Unitree's examples.
#
#   bash bench/conform-controller/venv_cyclone010.sh [VENV]      (default .venv-cyclone010)
#   UNITREE_PYTHON=.venv-cyclone010/bin/python UNITREE_SDK2_PYTHON_DIR=... bench/conform-controller/unitree_examples.sh python
#
# The source package looks for $CYCLONEDDS_HOME/{include,lib,bin}; Debian keeps the library in its multiarch
# directory, so a home of links is made inside the venv (the built binding loads libddsc through it: it stays).
set -euo pipefail
cd "$(dirname "$0")/../.."
venv=${1:-.venv-cyclone010}
[ -e /usr/include/dds/dds.h ] || { echo "venv_cyclone010.sh: Debian's cyclonedds-dev is missing (scripts/setup.sh installs it)" >&2; exit 2; }
python3 -m venv "$venv"
home=$(cd "$venv" && pwd)/cyclonedds-home
mkdir -p "$home"
ln -sfn /usr/include "$home/include"
ln -sfn "/usr/lib/$(gcc -print-multiarch)" "$home/lib"
ln -sfn /usr/bin "$home/bin"
# --no-cache-dir: a cached wheel would carry the library path of the home it was built against.
CYCLONEDDS_HOME=$home "$venv/bin/pip" install -q --no-cache-dir cyclonedds==0.10.2 numpy
"$venv/bin/python" -c 'import cyclonedds.__library__ as l; print("venv_cyclone010.sh: cyclonedds 0.10.2 on", l.library_path)'
