#!/usr/bin/env bash
# Set up hzval on a Debian machine with Python 3.11: Debian's LLVM 19 for
# Dr.Jit's CPU backend (Debian 12's default LLVM 15 crashes it), a virtualenv
# in .venv with hzval installed. `--test` adds what the test suite needs
# (gcc for the seed peer, chromium for the report's browser test, Mesa's EGL
# and llvmpipe for the GL techniques' tests).
# Safe to run again: it only does what is missing.
set -euo pipefail
cd "$(dirname "$0")"
tests=0
[[ "${1:-}" == "--test" ]] && tests=1

sudo=""
[[ "$(id -u)" -ne 0 ]] && sudo="sudo"
packages=()
ls /usr/lib/*-linux-gnu/libLLVM*.so.19* >/dev/null 2>&1 || packages+=(libllvm19)
python3 -c 'import ensurepip, venv' 2>/dev/null || packages+=(python3-venv)
if ((tests)); then
    command -v gcc >/dev/null || packages+=(gcc libc6-dev)
    # the report is tested in a real browser: Debian's chromium, driven by
    # Playwright's Python package (never `playwright install`: no downloads)
    [[ -x /usr/bin/chromium ]] || packages+=(chromium)
    # the GL techniques (horizon-gl, pom-gl; opt-in) are tested on Mesa's llvmpipe
    # through headless EGL: libEGL (glvnd), Mesa's EGL vendor library and its drivers
    ls /usr/lib/*-linux-gnu/libEGL.so.1 >/dev/null 2>&1 || packages+=(libegl1)
    ls /usr/lib/*-linux-gnu/libEGL_mesa.so.0 >/dev/null 2>&1 || packages+=(libegl-mesa0)
    ls /usr/lib/*-linux-gnu/dri/swrast_dri.so >/dev/null 2>&1 || packages+=(libgl1-mesa-dri)
fi
if ((${#packages[@]})); then
    echo "setup: installing Debian packages: ${packages[*]}"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${packages[@]}" >/dev/null
fi

[[ -x .venv/bin/python ]] || python3 -m venv .venv
# reinstall only when the project's requirements changed
stamp=.venv/.hzval-setup
want="$(sha256sum pyproject.toml | cut -d' ' -f1)"
if [[ ! -f $stamp ]] || ! grep -qxF "$want" "$stamp"; then
    echo "setup: installing hzval and its dependencies into .venv"
    # the test extra is small; with it, either command finds the venv complete
    .venv/bin/python -m pip install -q -e ".[test]"
    echo "$want" > "$stamp"
fi
