#!/usr/bin/env bash
# The wheel smoke suite: install a built benchbus wheel into a fresh virtual environment
# outside the source tree and run tests/wheel_smoke from a temporary directory, so nothing of
# the checkout is importable (no PYTHONPATH, another working directory).
#
#   .ci/wheel-smoke.sh [WHEEL]      default: the one benchbus wheel in dist/
#
# SMOKE_PYTHON is the interpreter the environment is made from (default python3). What the
# machine cannot give is deselected here, in one place, by the suite's markers: below Python
# 3.10 the simulators (pymodbus needs 3.10) and so the extras are not installed (-m "not
# sim"); on Windows there are no pseudo-terminals (-m "not pty").
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
smoke_python=${SMOKE_PYTHON:-python3}
if [ $# -gt 0 ]; then
    wheel=$1
else
    shopt -s nullglob
    wheels=("$root"/dist/benchbus-*.whl)
    [ ${#wheels[@]} -eq 1 ] || {
        echo "wheel-smoke: expected one benchbus wheel in dist/, found ${#wheels[@]} (make wheel)" >&2
        exit 1
    }
    wheel=${wheels[0]}
fi
# Absolute paths, in the form the interpreter takes (Git Bash on Windows: pwd -W gives C:/...).
native() { (cd "$1" && { pwd -W 2>/dev/null || pwd; }); }
wheel=$(native "$(dirname "$wheel")")/$(basename "$wheel")

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$smoke_python" -m venv "$tmp/venv"
if [ -x "$tmp/venv/bin/python" ]; then py=$tmp/venv/bin/python; else py=$tmp/venv/Scripts/python.exe; fi

markers=()
extras=""
if "$py" -c 'import sys; sys.exit(sys.version_info < (3, 10))'; then
    extras="[demo]"
else
    markers+=("not sim")
fi
if [ "$("$py" -c 'import os; print(os.name)')" = nt ]; then
    markers+=("not pty")
fi
select=()
if [ ${#markers[@]} -gt 0 ]; then
    joined=$(printf ' and %s' "${markers[@]}")
    select=(-m "${joined# and }")
fi

"$py" -m pip install --quiet --disable-pip-version-check "$wheel$extras" "pytest>=8"
cp -R "$root/tests/wheel_smoke" "$tmp/smoke"
cd "$tmp/smoke"
echo "wheel-smoke: $("$py" --version) from $(basename "$wheel")${extras:+ with $extras}${select[1]:+, -m \"${select[1]}\"}"
env -u PYTHONPATH BENCHBUS_CHECKOUT="$(native "$root")" "$py" -m pytest -q -p no:cacheprovider ${select[@]+"${select[@]}"}
