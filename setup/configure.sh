#!/bin/sh
# Finds the native libraries the build needs and writes their flags to the file $1 (make
# includes it as build/config.mk):
#   MPI      the compilers $FC and $CC (mpif90, mpicc) on PATH
#   PETSc    PETSC_DIR[/PETSC_ARCH]: PETSc's own PETSc.pc, or its lib/petsc/conf/petscvariables
#            without pkg-config; otherwise pkg-config's PETSc
#   HDF5     with its Fortran modules: HDF5_DIR, else pkg-config (hdf5-openmpi, hdf5-mpi, hdf5),
#            else the Fortran wrappers h5pfc or h5fc (`-show`)
#   SUNDIALS CVODE: SUNDIALS_DIR, else the compiler's default paths
#   LAPACK   the compiler's default paths
# What is missing is installed with apt-get on Debian as root ($NATIVE_PACKAGES; never with
# EME_SETUP_APT=no); anywhere else the script prints what to install (Debian, Spack,
# conda-forge) and stops with status 1.
set -u
output=$1
FC=${FC:-mpif90}
CC=${CC:-mpicc}

# A library `name` (libname.so or .a) in the directories of the -L flags $2, or where the
# compiler looks by default.
have_library() {
    for flag in $2; do
        case $flag in -L*) dir=${flag#-L}
            if [ -e "$dir/lib$1.so" ] || [ -e "$dir/lib$1.a" ] || [ -e "$dir/lib$1.dylib" ]; then return 0; fi ;;
        esac
    done
    command -v "$CC" >/dev/null 2>&1 || return 1
    for suffix in so a dylib; do
        case $("$CC" -print-file-name="lib$1.$suffix" 2>/dev/null) in /*) return 0 ;; esac
    done
    return 1
}

# Runtime paths for the -L directories, so that the programs find libraries outside the
# loader's default paths without LD_LIBRARY_PATH.
rpaths() {
    for flag in $1; do
        case $flag in -L*) printf ' -Wl,-rpath,%s' "${flag#-L}" ;; esac
    done
}

# The words of $1 without repeats, in order.
unique() {
    kept=''
    for word in $1; do
        case " $kept " in *" $word "*) ;; *) kept="$kept $word" ;; esac
    done
    printf '%s' "$kept"
}

# The first of the directories of the -I flags $2 that holds file $1.
include_holding() {
    for flag in $2; do
        case $flag in -I*) [ -e "${flag#-I}/$1" ] && { echo "${flag#-I}"; return 0; } ;; esac
    done
    return 1
}

find_libraries() {
    missing=''
    command -v "$FC" >/dev/null 2>&1 || missing="$missing MPI-Fortran-compiler($FC)"
    command -v "$CC" >/dev/null 2>&1 || missing="$missing MPI-C-compiler($CC)"

    # PETSc
    petsc_flags='' petsc_libs='' petsc_includes=''
    pc_dir=''
    if [ -n "${PETSC_DIR:-}" ]; then
        for dir in "$PETSC_DIR/${PETSC_ARCH:-}/lib/pkgconfig" "$PETSC_DIR/lib/pkgconfig"; do
            [ -e "$dir/PETSc.pc" ] && { pc_dir=$dir; break; }
        done
    fi
    if [ -n "$pc_dir" ] && command -v pkg-config >/dev/null 2>&1; then
        petsc_flags=$(PKG_CONFIG_PATH=$pc_dir pkg-config --cflags PETSc)
        petsc_libs=$(PKG_CONFIG_PATH=$pc_dir pkg-config --libs PETSc)
        petsc_includes=$(PKG_CONFIG_PATH=$pc_dir pkg-config --cflags-only-I PETSc)
    elif [ -n "${PETSC_DIR:-}" ]; then
        variables=''
        for file in "$PETSC_DIR/${PETSC_ARCH:-}/lib/petsc/conf/petscvariables" "$PETSC_DIR/lib/petsc/conf/petscvariables"; do
            [ -e "$file" ] && { variables=$file; break; }
        done
        if [ -n "$variables" ]; then
            petsc_includes=$(sed -n 's/^PETSC_FC_INCLUDES = //p' "$variables")
            petsc_flags=$petsc_includes
            petsc_libs=$(sed -n 's/^PETSC_WITH_EXTERNAL_LIB = //p' "$variables")
        fi
    elif command -v pkg-config >/dev/null 2>&1 && pkg-config --exists PETSc; then
        petsc_flags=$(pkg-config --cflags PETSc)
        petsc_libs=$(pkg-config --libs PETSc)
        petsc_includes=$(pkg-config --cflags-only-I PETSc)
    fi
    if [ -z "$petsc_libs" ] || ! include_holding petsc/finclude/petscsys.h "$petsc_includes" >/dev/null; then
        missing="$missing PETSc(with-Fortran)"
    fi
    petsc_libs="$petsc_libs$(rpaths "$petsc_libs")"

    # HDF5 with its Fortran interface
    hdf5_flags='' hdf5_dirs=''
    if [ -n "${HDF5_DIR:-}" ]; then
        hdf5_flags="-I$HDF5_DIR/include"
        hdf5_dirs="-L$HDF5_DIR/lib"
        [ -d "$HDF5_DIR/lib64" ] && hdf5_dirs="$hdf5_dirs -L$HDF5_DIR/lib64"
    else
        for package in hdf5-openmpi hdf5-mpi hdf5; do
            if command -v pkg-config >/dev/null 2>&1 && pkg-config --exists $package &&
               include_holding hdf5.mod "$(pkg-config --cflags-only-I $package)" >/dev/null; then
                hdf5_flags=$(pkg-config --cflags-only-I $package)
                hdf5_dirs=$(pkg-config --libs-only-L $package)
                break
            fi
        done
        if [ -z "$hdf5_flags" ]; then
            for wrapper in h5pfc h5fc; do
                command -v $wrapper >/dev/null 2>&1 || continue
                for word in $($wrapper -show 2>/dev/null); do
                    case $word in
                        -I*) hdf5_flags="$hdf5_flags $word" ;;
                        -L*) hdf5_dirs="$hdf5_dirs $word" ;;
                        /*libhdf5*) hdf5_dirs="$hdf5_dirs -L$(dirname "$word")" ;;
                    esac
                done
                hdf5_flags=$(unique "$hdf5_flags")
                [ -n "$hdf5_flags" ] && break
            done
        fi
    fi
    # The high-level libraries too: dimension scales (H5DS) and tables (H5TB).
    if ! include_holding hdf5.mod "$hdf5_flags" >/dev/null || ! have_library hdf5_fortran "$hdf5_dirs" ||
       ! have_library hdf5hl_fortran "$hdf5_dirs"; then
        missing="$missing HDF5(with-Fortran-and-high-level)"
    fi
    hdf5_dirs=$(unique "$hdf5_dirs")
    hdf5_libs="$hdf5_dirs$(rpaths "$hdf5_dirs") -lhdf5hl_fortran -lhdf5_hl -lhdf5_fortran -lhdf5"

    # SUNDIALS (CVODE with its dense direct solver)
    sundials_flags='' sundials_dirs=''
    if [ -n "${SUNDIALS_DIR:-}" ]; then
        sundials_flags="-I$SUNDIALS_DIR/include"
        for dir in lib lib64; do [ -d "$SUNDIALS_DIR/$dir" ] && sundials_dirs="$sundials_dirs -L$SUNDIALS_DIR/$dir"; done
        header_dirs=$sundials_flags
    else
        header_dirs='-I/usr/include -I/usr/local/include'
    fi
    if ! include_holding cvode/cvode.h "$header_dirs" >/dev/null || ! have_library sundials_cvode "$sundials_dirs"; then
        missing="$missing SUNDIALS(CVODE)"
    fi
    sundials_ldflags="$sundials_dirs$(rpaths "$sundials_dirs")"

    have_library lapack "" || missing="$missing LAPACK"
}

instructions() {
    cat <<EOF
The build needs:$missing
Install them with one of (then run make again):
  Debian/Ubuntu (as root, or with sudo):
    apt-get install $NATIVE_PACKAGES
  Spack:
    spack install openmpi petsc+mpi+fortran hdf5+fortran+hl+mpi sundials netlib-lapack pkgconf
    spack load openmpi petsc hdf5 sundials netlib-lapack pkgconf
  conda-forge:
    conda install -c conda-forge compilers openmpi openmpi-mpifort petsc 'hdf5=*=mpi_openmpi*' sundials liblapack pkg-config
Libraries outside the default paths are found through
  make PETSC_DIR=... [PETSC_ARCH=...] HDF5_DIR=... SUNDIALS_DIR=...
(PETSc: its PETSc.pc or petscvariables; HDF5: or h5pfc/h5fc on PATH; MPI: mpif90 and mpicc on PATH).
EOF
}

find_libraries
if [ -n "$missing" ]; then
    if [ "$(id -u)" = 0 ] && [ "${EME_SETUP_APT:-yes}" != no ] && command -v apt-get >/dev/null 2>&1; then
        echo "Missing:$missing; installing $NATIVE_PACKAGES with apt-get"
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $NATIVE_PACKAGES >/dev/null
        find_libraries
    fi
    if [ -n "$missing" ]; then
        instructions >&2
        exit 1
    fi
fi

mkdir -p "$(dirname "$output")"
cat > "$output" <<EOF
# Written by setup/configure.sh (make rewrites it when PETSC_DIR, PETSC_ARCH, HDF5_DIR or
# SUNDIALS_DIR change, or after make clean).
PETSC_FLAGS := $petsc_flags
PETSC_LIBS := $petsc_libs
PETSC_INCLUDES := $petsc_includes
HDF5_FLAGS := $hdf5_flags
HDF5_LIBS := $hdf5_libs
SUNDIALS_FLAGS := $sundials_flags
SUNDIALS_LDFLAGS := $sundials_ldflags
EOF
