#!/usr/bin/env bash
# One case of the CLI bad-input corpus: runs COMMAND and checks its exit code and that its output
# (stdout and stderr) contains MESSAGE, and that nothing crashed: no signal, no sanitizer report,
# no uncaught exception.
#
# usage: expect.sh CODE MESSAGE COMMAND [ARGS...]
set -u
expected_code=$1 message=$2
shift 2
output=$(timeout 300 "$@" 2>&1)
code=$?
failed=0
if [ "$code" != "$expected_code" ]; then
  echo "expect: exit code $code, expected $expected_code"
  failed=1
fi
if ! grep -qF -- "$message" <<< "$output"; then
  echo "expect: the output does not contain: $message"
  failed=1
fi
if grep -qE "runtime error:|AddressSanitizer|LeakSanitizer|terminate called|Segmentation fault|Aborted" <<< "$output"; then
  echo "expect: crash or sanitizer report"
  failed=1
fi
echo "--- $* (exit $code)"
head -c 4000 <<< "$output"
exit $failed
