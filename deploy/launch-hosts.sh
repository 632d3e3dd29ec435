#!/usr/bin/env bash
# The launch description of a run spread over hosts: the world server (with the Zenoh
# router) on one host, each robot's 14 module processes on its own host.
#
#   deploy/launch-hosts.sh world                 # on the world host (say 10.0.0.1)
#   deploy/launch-hosts.sh r1 10.0.0.1           # on robot r1's host
#   deploy/launch-hosts.sh r2 10.0.0.1           # ... one line per robot of the scenario
#
# The world host waits until every module of every robot is alive, then runs the
# scenario; each robot host keeps its modules supervised until the world server ends.
# SCENARIO, MODE and OUT may be overridden from the environment.
set -euo pipefail
role=${1:?usage: $0 world | ROBOT_ID ROUTER_ADDRESS}
SCENARIO=${SCENARIO:-crossing}
MODE=${MODE:-lockstep}
OUT=${OUT:-runs/$SCENARIO}
if [ "$role" = world ]; then
  exec cekm launch "$SCENARIO" --mode "$MODE" --robots none --listen 0.0.0.0 --out "$OUT"
fi
router=${2:?usage: $0 $role ROUTER_ADDRESS}
exec cekm launch "$SCENARIO" --mode "$MODE" --robots "$role" --no-world --connect "tcp/$router:7447" \
  --out "$OUT-$role"
