#!/bin/sh
# Certificates for a fleet with mutual TLS, made afresh (never commit them):
#   pki.sh DIR ROUTER_NAMES CN...
# DIR gets ca.pem/ca.key (the fleet's CA), router.pem/router.key (a server certificate valid for
# ROUTER_NAMES, e.g. "IP:10.77.0.1,IP:127.0.0.1,DNS:shore") and CN.pem/CN.key for each client
# identity (shore, vehicle-1, ...): its Common Name is what access control knows it by.
# ECDSA P-256 keys in PKCS#8, as Zenoh's TLS (rustls) reads them.
set -eu
dir=$1
names=$2
shift 2
mkdir -p "$dir"
cd "$dir"
openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes \
  -keyout ca.key -out ca.pem -days 30 -subj "/CN=tcpf fleet CA" \
  -addext "basicConstraints=critical,CA:TRUE" \
  -addext "keyUsage=critical,keyCertSign,cRLSign" 2>/dev/null
leaf() { # file stem, CN, extendedKeyUsage, subjectAltName (optional)
  openssl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes \
    -keyout "$1.key" -out "$1.csr" -subj "/CN=$2" 2>/dev/null
  {
    echo "basicConstraints=critical,CA:FALSE"
    echo "keyUsage=critical,digitalSignature"
    echo "extendedKeyUsage=$3"
    if [ -n "${4:-}" ]; then echo "subjectAltName=$4"; fi
  } > "$1.ext"
  openssl x509 -req -in "$1.csr" -CA ca.pem -CAkey ca.key -CAcreateserial \
    -out "$1.pem" -days 30 -sha256 -extfile "$1.ext" 2>/dev/null
  rm -f "$1.csr" "$1.ext"
}
leaf router router serverAuth "$names"
for cn in "$@"; do
  leaf "$cn" "$cn" clientAuth
done
chmod 600 ./*.key
