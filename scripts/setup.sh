#!/usr/bin/env bash
# Shared setup for the README commands: finds (or installs) the HDF5 system library and prints
# the cargo feature flags to use. Sourced by scripts/run-case.sh and scripts/test-all.sh.
#
# HDF5 output needs libhdf5-dev and pkg-config (Debian). When they are missing and we are root
# with apt-get, they are installed; otherwise sinterdem is built without HDF5 and says so in
# every run's log ("HDF5 output is off ...").
sinterdem_features() {
    if [ "${SINTERDEM_NO_HDF5:-0}" = "1" ]; then
        echo "setup: SINTERDEM_NO_HDF5=1, building without HDF5" >&2
        return 0
    fi
    if ! pkg-config --exists hdf5 2>/dev/null; then
        if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
            echo "setup: installing libhdf5-dev and pkg-config for HDF5 output (apt-get) ..." >&2
            if ! { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libhdf5-dev pkg-config; } >/tmp/sinterdem-apt.log 2>&1; then
                echo "setup: could not install libhdf5-dev (see /tmp/sinterdem-apt.log); building without HDF5 output" >&2
            fi
        else
            echo "setup: libhdf5-dev is not installed and cannot be installed here (not root or no apt-get); building without HDF5 output" >&2
        fi
    fi
    if pkg-config --exists hdf5 2>/dev/null; then
        echo "--features h5"
    fi
}

# hypre's BoomerAMG for `mechanics.solver = "hypre"` (the `hypre` cargo feature, docs/coupled.md
# "hypre") needs libhypre-dev (Debian; it pulls in Open MPI). Installed like libhdf5-dev when
# missing and we are root with apt-get. Returns 0 when the library is present; otherwise prints
# why not (SINTERDEM_HYPRE_SKIP holds the reason) and returns 1.
sinterdem_hypre() {
    SINTERDEM_HYPRE_SKIP=""
    local lib
    lib_present() { ls /usr/lib/*/libHYPRE.so /usr/lib/libHYPRE.so /usr/lib64/libHYPRE.so /usr/local/lib/libHYPRE.so 2>/dev/null | head -n 1; }
    lib=$(lib_present)
    if [ -z "$lib" ] && [ -n "${HYPRE_DIR:-}${HYPRE_LIB_DIR:-}" ]; then
        lib="${HYPRE_LIB_DIR:-${HYPRE_DIR:-}/lib}"
    fi
    if [ -z "$lib" ]; then
        if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
            echo "setup: installing libhypre-dev for the hypre solver tests (apt-get) ..." >&2
            if ! { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libhypre-dev; } >/tmp/sinterdem-apt-hypre.log 2>&1; then
                SINTERDEM_HYPRE_SKIP="apt-get install libhypre-dev failed (see /tmp/sinterdem-apt-hypre.log)"
            fi
            lib=$(lib_present)
        else
            SINTERDEM_HYPRE_SKIP="libhypre-dev is not installed and cannot be installed here (not root or no apt-get; set HYPRE_DIR to use another hypre build)"
        fi
    fi
    if [ -z "$lib" ]; then
        SINTERDEM_HYPRE_SKIP="${SINTERDEM_HYPRE_SKIP:-libHYPRE.so not found after installing libhypre-dev}"
        return 1
    fi
    return 0
}
