#!/usr/bin/env bash
# Set up mrnc-eval on a fresh Debian machine: system libraries the wheels need, then a
# virtual environment in .venv with the package installed (editable).
#
#   bash scripts/setup.sh          everything: SLAM, control, simulator, PDF, Dask, kiss-icp extras
#   bash scripts/setup.sh --test   also the test tools (evo, pytest, Chromium, pdftoppm)
#
# As root it installs the Debian packages itself; otherwise it prints the apt-get line to run.
set -euo pipefail
cd "$(dirname "$0")/.."

want_test=0
[[ "${1:-}" == "--test" ]] && want_test=1

# open3d: libusb (import), libGL/libgomp (rendering module, OpenMP); WeasyPrint: Pango;
# python3-venv: Debian's Python ships venv separately; gcc, python3-dev: the package's C extensions
# (setup.py): the SLAM's kernels (mrnc_eval/slam/_prep_kernels.c; without them `slam` and `nightly`
# stop and say so), the reader of TUM/KITTI text and APE's loops (without those, slower numpy/pandas paths).
pkgs=(libusb-1.0-0 libgl1 libgomp1 libpango-1.0-0 libpangoft2-1.0-0 libharfbuzz-subset0 fonts-dejavu-core python3-venv
      gcc python3-dev)
# Tests: headless Chromium opens the HTML report, pdftoppm renders the PDF.
(( want_test )) && pkgs+=(chromium poppler-utils)

missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if (( ${#missing[@]} )); then
  if [[ $(id -u) -eq 0 ]]; then
    echo "setup: installing system packages: ${missing[*]}" >&2
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    # chromium may be unavailable on some mirrors/architectures: tests then skip with a reason.
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null \
      || apt-get install -y -qq --no-install-recommends $(printf '%s\n' "${missing[@]}" | grep -v '^chromium$') >/dev/null
  else
    echo "setup: missing system packages; run as root:  apt-get install -y ${missing[*]}" >&2
  fi
fi

py=""
for cand in python3.11 python3.12 python3.13 python3; do
  if command -v "$cand" >/dev/null 2>&1 && "$cand" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
    py=$cand; break
  fi
done
[[ -n "$py" ]] || { echo "setup: Python >= 3.11 is required" >&2; exit 1; }

if [[ ! -x .venv/bin/python ]]; then
  "$py" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip >/dev/null
extras="all"  # the base install (pip install mrnc-eval) has no SLAM stack; this script installs all
(( want_test )) && extras="$extras,test"
.venv/bin/python -m pip install -q -e ".[${extras}]"
# setup.py's extensions are optional (the base install must not need a compiler): say so when the SLAM's were not built
.venv/bin/python -c 'import mrnc_eval.slam._prep_kernels' 2>/dev/null \
  || echo "setup: the SLAM's C kernels were not built (no gcc or python3-dev): install them and run this again" >&2
echo "setup: ready (.venv, extras: ${extras})" >&2
