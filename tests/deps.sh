#!/usr/bin/env bash
# Install the Debian packages crom needs to build, test and make pictures.
# Open MPI builds crom-fitfield's data-parallel training (issue 20); munge
# and Slurm's daemons are for tests/prog/slurm.sh, which starts a one-node
# cluster of its own from a generated slurm.conf (on a machine run by systemd,
# Debian enables their services: slurmctld and slurmd stay down without a
# /etc/slurm/slurm.conf, munged runs with the key Debian made).
# libwebsockets serves crom-view's page; Chromium and ChromeDriver
# (WebDriver), Python's websockets and PIL are for tests/prog/view.sh, which
# drives the page in a headless browser.
# Idempotent and non-interactive; uses sudo only when not root.
set -euo pipefail
PKGS="build-essential pkg-config libgmsh-dev gmsh libhdf5-dev hdf5-tools libmetis-dev
libsuitesparse-dev libopenblas-dev liblapacke-dev libarpack2-dev python3 python3-meshio
python3-h5py python3-numpy gnuplot-nox libpng-dev clang libclang-rt-14-dev libomp-14-dev
libopenmpi-dev openmpi-bin munge slurmctld slurmd slurm-client libwebsockets-dev chromium
chromium-driver python3-websockets python3-pil"
missing=()
for p in $PKGS; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "crom: installing missing Debian packages: ${missing[*]}" >&2
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
if ! $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}" >&2; then
  $SUDO apt-get update -q >&2
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}" >&2
fi
