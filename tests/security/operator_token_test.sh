#!/bin/bash
# Issue 35.9: hdeform-server refuses a guessable operator token at start (exit 2, naming the
# problem), starts with what --gen-token prints, and says so when the token is empty (what
# compose passes when the variable is unset).   usage: operator_token_test.sh HDEFORM_SERVER
set -u
server=$1
out=$(mktemp)
trap 'rm -f "$out"' EXIT
fail() { echo "FAIL: $*"; cat "$out"; exit 1; }

refused() {  # $1: the token, $2: what the message must say
  HDEFORM_ADMIN_TOKEN=$1 "$server" --no-state --port 0 >"$out" 2>&1
  [ $? -eq 2 ] || fail "token '$1' was not refused with exit 2"
  grep -q "HDEFORM_ADMIN_TOKEN refused: .*$2" "$out" || fail "token '$1': no message naming '$2'"
  grep -q 'listening on' "$out" && fail "token '$1': the server started"
  return 0
}
refused "                    " "printable ASCII without spaces"
refused "aaaaaaaaaaaaaaaa" "at least 32"
refused "abababababababababababababababababab" "distinct characters"
refused "0123456789abcdef0123456789abcdef,x" "commas"

token=$("$server" --gen-token) || fail "--gen-token failed"
[[ $token =~ ^[0-9a-f]{64}$ ]] || fail "--gen-token printed '$token', not 64 hex digits"
[ "$token" != "$("$server" --gen-token)" ] || fail "--gen-token printed the same token twice"

started() {  # runs the server for 2 s with HDEFORM_ADMIN_TOKEN=$1
  HDEFORM_ADMIN_TOKEN=$1 timeout 2 "$server" --no-state --port 0 >"$out" 2>&1
  [ $? -eq 124 ] || fail "the server with token '$1' did not keep running"
  grep -q 'listening on' "$out" || fail "the server with token '$1' did not listen"
}
started "$token"
started ""
grep -q 'no operator token' "$out" || fail "an empty token is not reported as 'no operator token'"
echo "operator token checks: ok"
