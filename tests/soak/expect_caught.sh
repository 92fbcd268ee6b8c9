#!/bin/sh
# The tests of the soak's own checks: horus_soak run with a fault injected into one steady process
# (--inject-hang ROLE, --inject-leak ROLE) must fail (exit status 1) and print a line naming it.
#   expect_caught.sh path/to/horus_soak PATTERN SOAK-ARGUMENT...
# PATTERN is a grep basic regular expression the line must match.
set -u
soak=$1
pattern=$2
shift 2
output=$("$soak" "$@" 2>&1)
status=$?
printf '%s\n' "$output"
if [ "$status" -ne 1 ]; then
  echo "expect_caught.sh: expected exit status 1 from the soak, got $status"
  exit 1
fi
if ! printf '%s\n' "$output" | grep -q "$pattern"; then
  echo "expect_caught.sh: no line matches '$pattern'"
  exit 1
fi
echo "expect_caught.sh: the soak failed and named the fault, as it must"
