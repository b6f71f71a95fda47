#!/usr/bin/env bash
# The Windows checks of `make cross`, on a Linux machine:
#   1. clippy for x86_64-pc-windows-gnu, with and without the Python bindings;
#   2. the Rust test suite built for Windows, run under wine;
#   3. the COM port tests (tests/windows_com.rs) under wine, through wine's serial code: COM
#      ports of a private wine prefix mapped to pseudo-terminals that `benchbus sim`
#      serves on the Linux side;
#   4. the Windows wheel (abi3, win_amd64) built and its contents checked (not imported:
#      there is no Windows Python here).
# Installs what it lacks: the mingw-w64 linker, wine, the Rust target. The wine prefix lives
# in target/wine (never ~/.wine); wine 8 lacks ProcessPrng, which Rust programs call at
# start-up, so a small DLL built from .ci/wine/bcryptprimitives.c provides it there.
#
# PYTHON: the Python with benchbus installed (the simulators) and maturin (the dev extra);
# the Makefile passes its virtual environment's.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
target=x86_64-pc-windows-gnu
python=${PYTHON:-.venv/bin/python}
step() { printf '\n== %s (%ds)\n' "$*" "$SECONDS"; }

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi; }

step "installing what is missing"
packages=()
command -v x86_64-w64-mingw32-gcc >/dev/null || packages+=(gcc-mingw-w64-x86-64)
[ -x /usr/lib/wine/wine64 ] || command -v wine64 >/dev/null || packages+=(wine64)
if ((${#packages[@]})); then
    as_root apt-get update -qq
    DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -qq "${packages[@]}" >/dev/null
fi
rustup target list --installed | grep -x "$target" >/dev/null || rustup target add "$target"

step "clippy for $target"
cargo clippy --quiet --all-targets --target "$target" -- -D warnings
cargo clippy --quiet --all-targets --target "$target" --features python -- -D warnings

step "wine prefix"
export WINEPREFIX="$root/target/wine" WINEDEBUG=-all
export CARGO_TARGET_X86_64_PC_WINDOWS_GNU_RUNNER="$root/.ci/wine/run"
control="$root/target/wine-com"
rm -rf "$control" && mkdir -p "$control"
pids=()
stop() {
    local pid
    # Wine's own processes (services.exe, plugplay.exe, winedevice.exe) outlive a killed
    # server and keep polling: the server's -k ends them with it.
    [ -n "${WINEPREFIX:-}" ] && .ci/wine/run --server -k 2>/dev/null || true
    for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
    for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
    pids=()
}
trap stop EXIT
# Wine's server, for this prefix, in the foreground: as the daemon wine starts otherwise it
# leads a session of its own, the first pseudo-terminal it opens for a COM port becomes its
# controlling terminal, and the hang-up the unplug test makes sends it SIGHUP (Debian's build
# then dumps all its objects on stderr). The server lingers until stopped.
.ci/wine/run --server -k 2>/dev/null || true
mkdir -p "$WINEPREFIX"
.ci/wine/run --server -f -p >"$control/wineserver.log" 2>&1 &
server=$!
pids+=("$server")
mkdir -p target/wine-shim
shim=target/wine-shim/bcryptprimitives.dll
if [ ! -f "$shim" ] || [ .ci/wine/bcryptprimitives.c -nt "$shim" ]; then
    x86_64-w64-mingw32-gcc -shared -O2 -Wall -o "$shim" \
        .ci/wine/bcryptprimitives.c .ci/wine/bcryptprimitives.def -ladvapi32
fi
if [ ! -f "$WINEPREFIX/system.reg" ]; then
    started=$SECONDS
    .ci/wine/run wineboot --init >/dev/null 2>&1
    echo "wineboot: $((SECONDS - started)) s"
fi
cp "$shim" "$WINEPREFIX/drive_c/windows/system32/bcryptprimitives.dll"
kill -0 "$server" 2>/dev/null || { echo "wineserver stopped:" >&2; cat "$control/wineserver.log" >&2; exit 1; }

step "the Rust test suite under wine"
cargo test --quiet --target "$target"

step "COM ports under wine"

# start_sim COMn: a simulated Taisong meter (unit 1) on a pseudo-terminal for COMn; its pid
# in $served. link_sim COMn: once it has said its pseudo-terminal, $WINEPREFIX/dosdevices/comn
# is a link to it.
start_sim() {
    "$python" -m benchbus sim instrument --baudrate 19200 >"$control/$1.out" 2>"$control/$1.err" &
    served=$!
    pids+=("$served")
}
link_sim() {
    local out="$control/$1.out" pty
    for _ in $(seq 200); do
        [ -s "$out" ] && break
        sleep 0.1
    done
    pty=$(head -n 1 "$out")
    [ -c "$pty" ] || { echo "the simulator for $1 gave no pseudo-terminal" >&2; cat "$control/$1.err" >&2; exit 1; }
    ln -sfn "$pty" "$WINEPREFIX/dosdevices/$1"
}
start_sim com5
start_sim com12
start_sim com6
unplugged=$served
for com in com5 com12 com6; do link_sim "$com"; done
# The unplug test's far end: gone at once when the test asks (SIGKILL, as an adapter pulled
# out: a SIGTERM lets the simulator stop its server first, which under wine has held the
# pseudo-terminal open past the test's 10 s), then served again on the same name once the
# test has met the loss (served sooner, on the same pseudo-terminal number, the reopen
# could hide it).
(
    trap 'kill "$served" 2>/dev/null; exit 0' TERM
    for _ in $(seq 600); do [ -e "$control/unplug" ] && break; sleep 0.05; done
    kill -KILL "$unplugged"
    wait "$unplugged" 2>/dev/null || true
    for _ in $(seq 600); do [ -e "$control/lost" ] && break; sleep 0.05; done
    start_sim com6
    link_sim com6
    touch "$control/replugged"
    wait "$served"
) &
pids+=("$!")
BENCHBUS_COM=COM5 BENCHBUS_COM_HIGH=COM12 BENCHBUS_COM_UNPLUG=COM6 \
    BENCHBUS_COM_CONTROL="Z:$control" \
    cargo test --quiet --target "$target" --test windows_com -- --ignored --test-threads=1
stop

step "the Windows wheel"
rm -rf target/wheels-windows
"$python" -m maturin build --quiet --target "$target" --out target/wheels-windows
"$python" - <<'EOF'
import pathlib
import sys
import zipfile

wheels = sorted(pathlib.Path("target/wheels-windows").glob("*.whl"))
names = [w.name for w in wheels]
if len(wheels) != 1 or not names[0].endswith("-cp39-abi3-win_amd64.whl"):
    sys.exit(f"expected one cp39-abi3-win_amd64 wheel, found {names}")
members = zipfile.ZipFile(wheels[0]).namelist()
for needed in ("benchbus/_core.pyd", "benchbus/__init__.py"):
    if needed not in members:
        sys.exit(f"{names[0]} lacks {needed}")
print(f"{names[0]}: {len(members)} files, benchbus/_core.pyd among them")
EOF

step "Windows checks passed"
