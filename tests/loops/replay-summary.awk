# The table of markloop-replay outputs (their --truth reports) read one after
# another: revisit events of 50 m or more closed, the other direction's, the
# median and p90 closure distance, and the wrong loops. `title` is its first
# line. Used by town-drives.sh and replay-table.sh.
/event at frame/ {
  if (match($0, /\): [0-9.]+ m/) == 0) next
  length_m = substr($0, RSTART + 3, RLENGTH - 5) + 0
  if (length_m < 50) next
  events++
  if ($0 ~ /opposite direction/) opposite++
  if (match($0, /closed at [0-9.]+ m/)) {
    closed_at[closed++] = substr($0, RSTART + 10, RLENGTH - 12) + 0
    if ($0 ~ /opposite direction/) opposite_closed++
  }
}
/^truth: / { wrong += $4 }
END {
  n = closed  # insertion sort, 1-based (mawk has no asort)
  for (i = 0; i < n; i++) {
    v = closed_at[i]
    for (j = i; j > 0 && sorted[j] > v; j--) sorted[j + 1] = sorted[j]
    sorted[j + 1] = v
  }
  for (i = 1; i <= n; i++) closed_at[i] = sorted[i]
  median = n == 0 ? 0 : (n % 2 ? closed_at[(n + 1) / 2] : (closed_at[n / 2] + closed_at[n / 2 + 1]) / 2)
  p90 = n == 0 ? 0 : closed_at[int(0.9 * (n - 1) + 0.5) + 1]
  printf "%s\n", title
  printf "  events of 50 m or more closed      %d / %d\n", closed, events
  printf "  ... the other direction            %d / %d\n", opposite_closed, opposite
  printf "  closed at, median / p90             %.1f / %.1f m\n", median, p90
  printf "  wrong loops                         %d\n", wrong
}
