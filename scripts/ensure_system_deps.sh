#!/usr/bin/env bash
# Make sure the system pieces satsight needs are present on Debian/Ubuntu:
#  - Python >= 3.11 with the venv module;
#  - a shared libLLVM >= 16 for Dr.Jit's CPU backend (Mitsuba's llvm_ad_rgb variant).
#    Debian 12's default LLVM 15 crashes Dr.Jit at the first kernel; libllvm19 works.
# Installs with apt when running as root, otherwise prints the exact command and fails.
set -euo pipefail

PYTHON=${PYTHON:-python3}
missing_pkgs=()

if ! command -v "$PYTHON" >/dev/null 2>&1; then
  missing_pkgs+=(python3 python3-venv)
elif ! "$PYTHON" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)'; then
  echo "satsight needs Python >= 3.11; $PYTHON is $("$PYTHON" --version 2>&1)." >&2
  echo "Install a newer Python (e.g. 'apt-get install python3.11 python3.11-venv') and run 'make PYTHON=python3.11 ...'." >&2
  exit 1
elif ! "$PYTHON" -c 'import ensurepip, venv' >/dev/null 2>&1; then
  missing_pkgs+=(python3-venv)
fi

have_llvm() {
  local dir
  for dir in /usr/lib/x86_64-linux-gnu /usr/lib/aarch64-linux-gnu /usr/lib64 /usr/lib /usr/local/lib; do
    compgen -G "$dir/libLLVM-19*.so*" >/dev/null 2>&1 && return 0
    compgen -G "$dir/libLLVM.so.19*" >/dev/null 2>&1 && return 0
    compgen -G "$dir/libLLVM-1[6-8]*.so*" >/dev/null 2>&1 && return 0
    compgen -G "$dir/libLLVM-2[0-9]*.so*" >/dev/null 2>&1 && return 0
  done
  [ -n "${DRJIT_LIBLLVM_PATH:-}" ] && [ -f "$DRJIT_LIBLLVM_PATH" ] && return 0
  return 1
}
have_llvm || missing_pkgs+=(libllvm19)

if [ ${#missing_pkgs[@]} -eq 0 ]; then
  exit 0
fi

if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
  echo "Installing system packages: ${missing_pkgs[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq "${missing_pkgs[@]}"
else
  echo "satsight needs these system packages: ${missing_pkgs[*]}" >&2
  echo "Run:  sudo apt-get update && sudo apt-get install -y ${missing_pkgs[*]}" >&2
  exit 1
fi
