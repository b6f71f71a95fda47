#!/usr/bin/env bash
# Install the Debian packages of the commands the tests need, when a command is missing:
#   .ci/need.sh chromium            (the command and its package share a name)
#   .ci/need.sh COMMAND=PACKAGE ...
# As root, or through sudo. Nothing happens when every command is there.
set -euo pipefail
packages=()
for need in "$@"; do
    command=${need%%=*}
    package=${need#*=}
    command -v "$command" >/dev/null || packages+=("$package")
done
((${#packages[@]})) || exit 0
as_root() { if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi; }
echo "installing ${packages[*]} (apt-get)" >&2
as_root apt-get update -qq
DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -qq "${packages[@]}" >/dev/null
