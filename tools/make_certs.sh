#!/bin/sh
# TLS with client certificates for the Zenoh router (docs/live.md, "Access control"): a private CA, the router's
# certificate and one client certificate per role, whose common name is the role the router's access control gives
# it. Needs openssl (1.1.1 or 3.x).
#
#   tools/make_certs.sh DIR [ROLE ...]        # roles default to: plant supervisor api viewer
#   WINDWARDEN_TLS_HOSTS=zenoh,localhost,127.0.0.1 tools/make_certs.sh docker/certs
#
# Writes DIR/ca.pem (give it to every client), DIR/router.pem and router.key (the router's identity, valid for the
# names in WINDWARDEN_TLS_HOSTS, default localhost,127.0.0.1), and DIR/<role>.pem and <role>.key. Keys are
# created with mode 0600; keep ca.key offline once the certificates are made.
set -eu
[ $# -ge 1 ] || { echo "usage: $0 DIR [ROLE ...]" >&2; exit 2; }
dir=$1
shift
roles=${*:-plant supervisor api viewer}
hosts=${WINDWARDEN_TLS_HOSTS:-localhost,127.0.0.1}
days=${WINDWARDEN_TLS_DAYS:-365}
umask 077
mkdir -p "$dir"

san=""
for h in $(echo "$hosts" | tr ',' ' '); do
    case $h in
        *[!0-9.:]*) entry="DNS:$h" ;;
        *) entry="IP:$h" ;;
    esac
    san="${san:+$san,}$entry"
done

key() { openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$1" 2>/dev/null; }

key "$dir/ca.key"
openssl req -x509 -new -key "$dir/ca.key" -days "$days" -subj "/CN=windwarden-ca" \
    -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
    -out "$dir/ca.pem"

sign() {  # sign NAME EXTENSIONS
    key "$dir/$1.key"
    openssl req -new -key "$dir/$1.key" -subj "/CN=$1" -out "$dir/$1.csr"
    printf '%s\n' "$2" >"$dir/$1.ext"
    openssl x509 -req -in "$dir/$1.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" -CAcreateserial -days "$days" \
        -extfile "$dir/$1.ext" -out "$dir/$1.pem" 2>/dev/null
    rm -f "$dir/$1.csr" "$dir/$1.ext"
}

sign router "basicConstraints=CA:FALSE
keyUsage=critical,digitalSignature
extendedKeyUsage=serverAuth
subjectAltName=$san"
for role in $roles; do
    sign "$role" "basicConstraints=CA:FALSE
keyUsage=critical,digitalSignature
extendedKeyUsage=clientAuth"
done
rm -f "$dir/ca.srl"
chmod 0644 "$dir"/*.pem
echo "wrote ca.pem, router.pem/.key and $(echo "$roles" | sed 's/ /, /g') (.pem/.key) in $dir"
