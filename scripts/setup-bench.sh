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
"$(dirname "${BASH_SOURCE[0]}")/apt-install.sh" setup-bench libsundials-cvode6
