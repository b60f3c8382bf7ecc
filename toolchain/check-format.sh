#!/usr/bin/env bash
# Fails when a tracked C++ file differs from .clang-format's layout. Run with --fix to rewrite.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
mapfile -t files < <(git ls-files '*.cpp' '*.hpp' '*.h' '*.cc')
if ((${#files[@]} == 0)); then echo "check-format: no C++ files"; exit 0; fi
if [[ "${1:-}" == "--fix" ]]; then
  clang-format -i "${files[@]}"
  echo "check-format: formatted ${#files[@]} files"
  exit 0
fi
if clang-format --dry-run -Werror "${files[@]}" 2>/tmp/hwr-format.log; then
  echo "check-format: ${#files[@]} files clean"
else
  grep -E '^[^ ].*(warning|error):' /tmp/hwr-format.log | cut -d: -f1 | sort -u | sed 's/^/needs clang-format: /'
  echo "check-format: run toolchain/check-format.sh --fix"
  exit 1
fi
