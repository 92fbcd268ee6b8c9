#!/bin/sh
# soak.detects_hang.<role>: horus_soak with the steady <role> made to hang (--inject-hang) must
# fail (exit status 1) and name that process in a STUCK line while it is still alive.
#   expect_stuck.sh path/to/horus_soak ROLE
set -u
soak=$1
role=$2
output=$("$soak" --seconds 8 --stuck-seconds 3 --inject-hang "$role" 2>&1)
status=$?
printf '%s\n' "$output"
if [ "$status" -ne 1 ]; then
  echo "expect_stuck.sh: expected exit status 1 from the soak, got $status"
  exit 1
fi
if ! printf '%s\n' "$output" |
  grep -q "^horus_soak: STUCK $role [0-9]* (steady), pid [0-9]*: no progress for"; then
  echo "expect_stuck.sh: the hung $role was not reported as stuck"
  exit 1
fi
echo "expect_stuck.sh: the hung $role was named and the soak failed, as it must"
