#!/usr/bin/env bash
# The benchmark's peer integrator: SUNDIALS CVODE, loaded by the bench at run time from
# libsundials_cvode.so.6 (Debian package libsundials-cvode6; it carries the serial N_Vector,
# dense matrix and dense linear solver too). The bench needs no headers: libsundials-dev,
# whose dependency tree (MPI, HDF5, PETSc) does not even install on every Debian system,
# is not needed. Installs the package with apt-get when the library is missing.
set -euo pipefail

if ldconfig -p | grep -q 'libsundials_cvode\.so\.6 '; then
    exit 0
fi
if ! command -v apt-get >/dev/null; then
    echo "setup-bench.sh: libsundials_cvode.so.6 not found and no apt-get; install SUNDIALS 6 CVODE" >&2
    exit 1
fi
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends libsundials-cvode6
