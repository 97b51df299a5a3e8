# Shell helpers to run a local mlsreg server in the background (sourced by demo and e2e tests).
# start_server LOGFILE ARGS...  -> sets MLSREG_SERVER_PID and MLSREG_SERVER_ADDRESS
start_server() {
  local log=$1; shift
  "$MLSREG" serve --listen 127.0.0.1:0 "$@" >"$log" 2>&1 &
  MLSREG_SERVER_PID=$!
  for _ in $(seq 1 100); do
    MLSREG_SERVER_ADDRESS=$( (grep -o 'listening on [0-9.]*:[0-9]*' "$log" || true) | head -1 | awk '{print $3}')
    if [ -n "$MLSREG_SERVER_ADDRESS" ]; then return 0; fi
    if ! kill -0 "$MLSREG_SERVER_PID" 2>/dev/null; then cat "$log" >&2; return 1; fi
    sleep 0.1
  done
  echo "server did not start:" >&2; cat "$log" >&2
  return 1
}

# stop_server: SIGTERM (drain), wait, return the server's exit code.
stop_server() {
  kill -TERM "$MLSREG_SERVER_PID" 2>/dev/null || true
  wait "$MLSREG_SERVER_PID"
}
