#!/usr/bin/env bash
# README command 1: install the dependencies, build, and run the main job (agvnav-hil) on its
# embedded default scenario. Extra arguments go to agvnav-hil.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
cmake --preset default
cmake --build --preset default -j "$(nproc)" --target agvnav-hil  # only what the main job needs
exec build/default/apps/hil/agvnav-hil "$@"
