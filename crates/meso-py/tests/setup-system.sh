#!/usr/bin/env bash
# Debian packages the Python tests need: libllvm19 for Mitsuba's vectorised llvm_ad_rgb variant
# (Debian 12's libLLVM-15 crashes Dr.Jit; docs/mitsuba.md). Installed when missing.
set -euo pipefail
if [ ! -e /usr/lib/x86_64-linux-gnu/libLLVM-19.so ] && [ ! -e /usr/lib/x86_64-linux-gnu/libLLVM-19.so.1 ]; then
  sudo_cmd=""
  if [ "$(id -u)" != "0" ] && command -v sudo >/dev/null 2>&1; then sudo_cmd="sudo"; fi
  echo "python: installing libllvm19 (apt-get)" >&2
  $sudo_cmd apt-get update && DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y libllvm19
fi
