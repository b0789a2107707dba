# Sourced by the scripted tests: comparisons that fail when their number is missing.
# A value read from a log or a report with grep/sed is empty when the line is absent, and
# awk compares an empty string with a limit as text: a check written as awk alone passes
# when the number is lost. These fail then, naming what was missing.

# is_number VALUE: a finite decimal number (no NaN, no inf, not empty).
is_number() {
  [[ "$1" =~ ^[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?$ ]]
}

# check_below NAME VALUE LIMIT: VALUE is a finite number below LIMIT; otherwise one line
# naming NAME and the value (or that it is missing) on stdout and status 1.
check_below() {
  local name="$1" value="$2" limit="$3"
  if ! is_number "$value"; then echo "$name: no number (got '$value')"; return 1; fi
  awk -v v="$value" -v l="$limit" 'BEGIN { exit !(v + 0 < l + 0) }' || { echo "$name: $value, not below $limit"; return 1; }
}

# check_between NAME VALUE LOW HIGH: LOW <= VALUE <= HIGH, a finite number.
check_between() {
  local name="$1" value="$2" low="$3" high="$4"
  if ! is_number "$value"; then echo "$name: no number (got '$value')"; return 1; fi
  awk -v v="$value" -v a="$low" -v b="$high" 'BEGIN { exit !(v + 0 >= a + 0 && v + 0 <= b + 0) }' ||
    { echo "$name: $value, not in [$low, $high]"; return 1; }
}
