#!/usr/bin/env bash
# The launch description of a run spread over hosts: the world server (with the Zenoh
# router) on one host, each robot's 14 module processes on its own host.
#
#   deploy/launch-hosts.sh world                 # on the world host (say 10.0.0.1), router included
#   deploy/launch-hosts.sh world 10.0.0.9        # or joining a separately run router (access control)
#   deploy/launch-hosts.sh r1 10.0.0.1           # on robot r1's host
#   deploy/launch-hosts.sh r2 10.0.0.1           # ... one line per robot of the scenario
#
# The world host waits until every module of every robot is alive, then runs the
# scenario; each robot host keeps its modules supervised until the world server ends.
# Robot hosts fetch the trained model from the world host's launcher (no copy needed).
# SCENARIO, MODE and OUT may be overridden from the environment; with ZENOH_CONFIG set
# (a client config with credentials, e.g. deploy/robot-r1.json5) every process started
# on the host logs in with it.
set -euo pipefail
role=${1:?usage: $0 world | ROBOT_ID ROUTER_ADDRESS}
SCENARIO=${SCENARIO:-crossing}
MODE=${MODE:-lockstep}
OUT=${OUT:-runs/$SCENARIO}
extra=()
if [ -n "${ZENOH_CONFIG:-}" ]; then
  extra=(--config "$ZENOH_CONFIG")
fi
if [ "$role" = world ]; then
  if [ -n "${2:-}" ]; then  # a separately run router (access control): join it
    exec cekm launch "$SCENARIO" --mode "$MODE" --robots none --connect "tcp/$2:7447" --out "$OUT" "${extra[@]}"
  fi
  exec cekm launch "$SCENARIO" --mode "$MODE" --robots none --listen 0.0.0.0 --out "$OUT" "${extra[@]}"
fi
router=${2:?usage: $0 $role ROUTER_ADDRESS}
exec cekm launch "$SCENARIO" --mode "$MODE" --robots "$role" --no-world --connect "tcp/$router:7447" \
  --model-from-zenoh --out "$OUT-$role" "${extra[@]}"
