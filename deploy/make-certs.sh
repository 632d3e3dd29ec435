#!/usr/bin/env bash
# A local certificate authority and one certificate per host, for mutual TLS between
# the Zenoh router and every client (deploy/tls/*.json5; see deploy/README.md).
#
#   deploy/make-certs.sh DIR [ROUTER_NAME_OR_IP ...]
#
# writes into DIR (created if missing; existing files are never overwritten):
#   ca.pem, ca.key          the certificate authority (keep ca.key off the run's hosts)
#   router.pem, router.key  the router's certificate, valid for the names and IP
#                           addresses given (default: cekm-router.local localhost 127.0.0.1);
#                           a client checks the name or address in its tls/HOST:PORT
#                           locator against these
#   NAME.pem, NAME.key      one per identity, common name NAME: the router's access
#                           control knows each client by it (HOSTS, default
#                           "world r1 r2 r3 r4 monitor operator")
# Keys are EC P-256 (PKCS#8), certificates last DAYS days (default 825).
set -euo pipefail
dir=${1:?usage: $0 DIR [ROUTER_NAME_OR_IP ...]}
shift
routers=("$@")
if [ ${#routers[@]} -eq 0 ]; then
  routers=(cekm-router.local localhost 127.0.0.1)
fi
HOSTS=${HOSTS:-world r1 r2 r3 r4 monitor operator}
DAYS=${DAYS:-825}
command -v openssl >/dev/null || { echo "make-certs.sh: openssl not found (apt-get install openssl)" >&2; exit 1; }
mkdir -p "$dir"
umask 077

check_name() {  # a certificate name: letters, digits, '.', '-', '_' only
  if ! [[ $1 =~ ^[A-Za-z0-9._-]+$ ]]; then
    echo "make-certs.sh: '$1' is not a valid name (letters, digits, '.', '-', '_')" >&2; exit 1
  fi
}

new_key() {
  openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$1" 2>/dev/null
}

if [ -e "$dir/ca.key" ] || [ -e "$dir/ca.pem" ]; then
  echo "make-certs.sh: $dir/ca.pem exists; using it (delete $dir to start over)" >&2
  [ -e "$dir/ca.key" ] || { echo "make-certs.sh: $dir/ca.key missing: cannot sign" >&2; exit 1; }
else
  new_key "$dir/ca.key"
  openssl req -x509 -new -key "$dir/ca.key" -sha256 -days "$DAYS" -subj "/CN=cekm local CA" \
    -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
    -out "$dir/ca.pem"
fi

issue() {  # issue NAME SAN: a key and a certificate signed by the CA, for server and client use
  local name=$1 san=$2 ext
  if [ -e "$dir/$name.pem" ]; then
    echo "make-certs.sh: $dir/$name.pem exists; kept" >&2
    return
  fi
  ext=$(mktemp)
  printf '%s\n' "basicConstraints=critical,CA:FALSE" "keyUsage=critical,digitalSignature" \
    "extendedKeyUsage=serverAuth,clientAuth" "subjectAltName=$san" >"$ext"
  new_key "$dir/$name.key"
  openssl req -new -key "$dir/$name.key" -subj "/CN=$name" -out "$dir/$name.csr"
  openssl x509 -req -in "$dir/$name.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" -CAcreateserial \
    -days "$DAYS" -sha256 -extfile "$ext" -out "$dir/$name.pem" 2>/dev/null
  rm -f "$dir/$name.csr" "$ext"
  echo "$dir/$name.pem: CN=$name, $san"
}

san=""
for r in "${routers[@]}"; do
  check_name "$r"
  if [[ $r =~ ^[0-9.]+$ || $r == *:* ]]; then san+="${san:+,}IP:$r"; else san+="${san:+,}DNS:$r"; fi
done
issue router "$san"
for h in $HOSTS; do
  check_name "$h"
  issue "$h" "DNS:$h"
done
chmod 644 "$dir"/*.pem
