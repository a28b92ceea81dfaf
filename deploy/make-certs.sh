#!/usr/bin/env bash
# Makes a private CA and certificates for Reenact's TLS, with openssl:
#   deploy/make-certs.sh OUT_DIR [HOST_OR_IP ...]
# OUT_DIR/ca.pem      the CA certificate (clients: --tls-ca / REENACT_TLS_CA)
# OUT_DIR/server.pem  server certificate for localhost, 127.0.0.1, ::1 and the
# OUT_DIR/server.key  hosts given (reenact-server / reenactd: --tls-cert, --tls-key)
# OUT_DIR/client.pem  a client certificate, for servers started with
# OUT_DIR/client.key  --tls-client-ca OUT_DIR/ca.pem
# Keys are EC P-256, mode 0600; certificates are valid for 825 days.
set -euo pipefail
if [[ $# -lt 1 || "$1" == -* ]]; then
  echo "usage: deploy/make-certs.sh OUT_DIR [HOST_OR_IP ...]" >&2
  exit 2
fi
command -v openssl >/dev/null || { echo "make-certs: openssl is not installed (apt-get install openssl)" >&2; exit 1; }
out="$1"
shift
mkdir -p "$out"
chmod 700 "$out"
umask 077
san="DNS:localhost,IP:127.0.0.1,IP:::1"
for host in "$@"; do
  if [[ "$host" =~ ^[0-9.]+$ || "$host" == *:* ]]; then san+=",IP:$host"; else san+=",DNS:$host"; fi
done
key() { openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$1" 2>/dev/null; }
key "$out/ca.key"
openssl req -x509 -new -key "$out/ca.key" -sha256 -days 825 -subj "/CN=Reenact private CA" \
  -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
  -out "$out/ca.pem" 2>/dev/null
sign() {  # name subject extensions
  key "$out/$1.key"
  openssl req -new -key "$out/$1.key" -subj "$2" -out "$out/$1.csr" 2>/dev/null
  printf '%s\n' "$3" >"$out/$1.ext"
  openssl x509 -req -in "$out/$1.csr" -CA "$out/ca.pem" -CAkey "$out/ca.key" -CAcreateserial \
    -sha256 -days 825 -extfile "$out/$1.ext" -out "$out/$1.pem" 2>/dev/null
  rm -f "$out/$1.csr" "$out/$1.ext"
}
sign server "/CN=reenact-server" "subjectAltName=$san
extendedKeyUsage=serverAuth
basicConstraints=CA:FALSE"
sign client "/CN=reenact-client" "extendedKeyUsage=clientAuth
basicConstraints=CA:FALSE"
rm -f "$out/ca.srl"
chmod 644 "$out/ca.pem" "$out/server.pem" "$out/client.pem"
echo "make-certs: $out/ca.pem, server.pem/.key ($san), client.pem/.key"
