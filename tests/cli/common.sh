# Shared by the command-line test scripts (sourced).
fail() { echo "FAIL: $*"; exit 1; }

# wait_for_log FILE PATTERN PID: waits (up to 60 s) until FILE has a line matching the grep PATTERN or PID ends;
# fails the test if the line never came.
wait_for_log() {
  local file=$1 pattern=$2 pid=$3
  for _ in $(seq 1 1200); do
    grep -q "$pattern" "$file" 2>/dev/null && return 0
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.05
  done
  grep -q "$pattern" "$file" || fail "never saw '$pattern': $(tail -2 "$file")"
}
