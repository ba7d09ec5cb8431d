#!/usr/bin/env bash
# Prints line N (1 or 2) of the README's Quick start block, so CI runs the README's own words.
set -euo pipefail
n="$1"
awk '/^## Quick start/{f=1} f&&/^```bash/{b=1;next} b&&/^```/{exit} b' "$(dirname "$0")/../README.md" | sed -n "${n}p"
