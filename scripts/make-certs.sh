#!/bin/sh
# Make a certificate authority and TLS certificates for a mstc deployment (docs/security.md).
#
#   scripts/make-certs.sh DIR [--host NAME_OR_IP]... [--client COMMON_NAME]...
#
# DIR gets ca.pem/ca.key (keep ca.key offline: whoever holds it can mint any role),
# router.pem/router.key for the router (valid for every --host, default localhost and
# 127.0.0.1) and CN.pem/CN.key per --client. A client certificate's common name is its role
# (robot_3, simhw, operator, observer): with mTLS the router's ACL maps it to that role.
# Existing files are kept, so re-running adds clients without replacing the CA.
set -eu
umask 077
[ $# -ge 1 ] || { echo "usage: $0 DIR [--host H]... [--client CN]..." >&2; exit 2; }
command -v openssl >/dev/null || { echo "$0: openssl not found" >&2; exit 1; }
dir=$1; shift
hosts=""; clients=""
while [ $# -gt 0 ]; do
    case $1 in
        --host) hosts="$hosts $2"; shift 2 ;;
        --client) clients="$clients $2"; shift 2 ;;
        *) echo "$0: unknown argument $1" >&2; exit 2 ;;
    esac
done
[ -n "$hosts" ] || hosts="localhost 127.0.0.1"
mkdir -p "$dir"
days=825

key() { [ -f "$1" ] || openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$1" 2>/dev/null; }

if [ ! -f "$dir/ca.pem" ]; then
    key "$dir/ca.key"
    openssl req -x509 -new -key "$dir/ca.key" -sha256 -days "$days" -subj "/CN=mstc-ca" \
        -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
        -out "$dir/ca.pem"
fi

# leaf NAME CN USAGE SAN
leaf() {
    [ -f "$dir/$1.pem" ] && return 0
    key "$dir/$1.key"
    ext="$dir/$1.ext"
    {
        echo "basicConstraints=critical,CA:FALSE"
        echo "keyUsage=critical,digitalSignature,keyEncipherment"
        echo "extendedKeyUsage=$3"
        [ -n "$4" ] && echo "subjectAltName=$4"
    } > "$ext"
    openssl req -new -key "$dir/$1.key" -subj "/CN=$2" -out "$dir/$1.csr"
    openssl x509 -req -in "$dir/$1.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" \
        -CAcreateserial -days "$days" -sha256 -extfile "$ext" -out "$dir/$1.pem" 2>/dev/null
    rm -f "$dir/$1.csr" "$ext"
}

san=""
for h in $hosts; do
    case $h in
        *[!0-9.:]*) entry="DNS:$h" ;;
        *) entry="IP:$h" ;;
    esac
    san="${san:+$san,}$entry"
done
leaf router mstc-router serverAuth,clientAuth "$san"  # also to join other routers
for c in $clients; do
    leaf "$c" "$c" clientAuth ""
done
echo "certificates in $dir"
