#!/usr/bin/env bash
# The launch description of a run spread over hosts: the world server (with the Zenoh
# router) on one host, each robot's 14 module processes on its own host.
#
#   deploy/launch-hosts.sh world                 # on the world host (say 10.0.0.1), router included
#   deploy/launch-hosts.sh world 10.0.0.9        # or joining a separately run router (access control)
#   deploy/launch-hosts.sh r1 10.0.0.1           # on robot r1's host
#   deploy/launch-hosts.sh r2 10.0.0.1           # ...
#   deploy/launch-hosts.sh r3 10.0.0.1           # one line per robot of the scenario (crossing: r1-r3)
#   deploy/launch-hosts.sh r1 10.0.0.1 --seed 2  # options after these go to cekm launch
#
# The world host waits until every module of every robot is alive, then runs the
# scenario; each robot host keeps its modules supervised until the world server ends.
# Robot hosts fetch the trained model from the world host's launcher (no copy needed).
# SCENARIO, MODE and OUT may be overridden from the environment; with ZENOH_CONFIG set
# (a client config with credentials, e.g. deploy/robot-r1.json5) every process started
# on the host logs in with it. LINK=tls joins a separately run router over TLS
# (deploy/tls/router.json5, client configs deploy/tls/*.json5); PORT is the router's
# port (7447).
set -euo pipefail
role=${1:?usage: $0 world [ROUTER_ADDRESS] | ROBOT_ID ROUTER_ADDRESS, then cekm launch options}
shift
router=""
if [ $# -gt 0 ] && [[ $1 != -* ]]; then
  router=$1
  shift
fi
SCENARIO=${SCENARIO:-crossing}
MODE=${MODE:-lockstep}
OUT=${OUT:-runs/$SCENARIO}
LINK=${LINK:-tcp}
PORT=${PORT:-7447}
extra=()
if [ -n "${ZENOH_CONFIG:-}" ]; then
  extra=(--config "$ZENOH_CONFIG")
fi
if [ "$role" = world ]; then
  if [ -n "$router" ]; then  # a separately run router (access control, TLS): join it
    exec cekm launch "$SCENARIO" --mode "$MODE" --robots none --connect "$LINK/$router:$PORT" --out "$OUT" \
      "${extra[@]}" "$@"
  fi
  if [ "$LINK" != tcp ]; then
    echo "launch-hosts.sh: the world server's own router listens on tcp; for LINK=$LINK run deploy/tls/router.json5 and give its address" >&2
    exit 2
  fi
  exec cekm launch "$SCENARIO" --mode "$MODE" --robots none --listen 0.0.0.0 --port "$PORT" --out "$OUT" \
    "${extra[@]}" "$@"
fi
if [ -z "$router" ]; then
  echo "usage: $0 $role ROUTER_ADDRESS [cekm launch options]" >&2
  exit 2
fi
exec cekm launch "$SCENARIO" --mode "$MODE" --robots "$role" --no-world --connect "$LINK/$router:$PORT" \
  --model-from-zenoh --out "$OUT-$role" "${extra[@]}" "$@"
