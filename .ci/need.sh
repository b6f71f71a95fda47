#!/usr/bin/env bash
# Install the Debian packages of the commands the tests need, when a command is missing:
#   .ci/need.sh chromium                          (the command and its package share a name)
#   .ci/need.sh COMMAND=PACKAGE ...
#   .ci/need.sh 'chromium|chromium-browser=chromium'   (any one of these commands will do)
# As root, or through sudo. Nothing happens when every command is there.
set -euo pipefail
packages=()
for need in "$@"; do
    commands=${need%%=*}
    package=${need#*=}
    found=
    IFS='|' read -ra alternatives <<<"$commands"
    for command in "${alternatives[@]}"; do
        command -v "$command" >/dev/null && found=1
    done
    [ -n "$found" ] || packages+=("$package")
done
((${#packages[@]})) || exit 0
fail() {
    echo "$0: the tests need the Debian package(s) ${packages[*]}: $1." >&2
    echo "  Install them yourself (apt-get install ${packages[*]}), then run again." >&2
    exit 1
}
command -v apt-get >/dev/null || fail "there is no apt-get here"
if [ "$(id -u)" = 0 ]; then
    as_root() { "$@"; }
elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then
    as_root() { sudo "$@"; }
else
    fail "installing them needs root, and sudo is missing or asks for a password"
fi
echo "installing ${packages[*]} (apt-get)" >&2
as_root apt-get update -qq || fail "apt-get update failed"
DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -qq "${packages[@]}" >/dev/null ||
    fail "apt-get install failed"
