#!/usr/bin/env bash
# make-certs.sh - DDS Security (OMG DDS-Security 1.1) material for the MAV stack's Cyclone DDS domain.
#
# Usage:
#   deploy/dds-security/make-certs.sh OUT [--days N] [--force]
#       [--protection NONE|SIGN|ENCRYPT] [--rtps-protection K] [--metadata-protection K]
#       [--data-protection K] [--domain ID|any] [--plugin-dir DIR]
#       [--extra-test NAME]... [--extra-expired NAME]... [--extra-foreign NAME]...
#
# What it makes (all paths below OUT, which must not exist unless --force is given; with
# --force an OUT made earlier by this script is replaced, anything else is refused):
#   ca/identity_ca.{pem,key}      identity CA (EC prime256v1, self-signed); signs the identities
#   ca/permissions_ca.{pem,key}   permissions CA (EC prime256v1, self-signed); signs the
#                                 governance and every permissions document (S/MIME, text mode)
#   ca/governance.xml             the governance document (shared by every participant)
#   <program>/                    one identity per program: mav-simulator mav-localization
#                                 mav-mapping mav-planning mav-control mavctl mav-load
#       cert.pem  key.pem (0600)  identity, subject CN=<program>, signed by the identity CA
#       identity_ca.pem  permissions_ca.pem  governance.p7s
#       permissions.xml  permissions.p7s   its grant: the topics it may publish/subscribe
#                                 (table PUB/SUB below), validity = the certificate's, default DENY
#       security.xml              <CycloneDDS><Domain id="any"><Security>...</Security></Domain>
#                                 with absolute file:// URIs; merge it with deploy/cyclonedds.xml:
#          CYCLONEDDS_URI="file://$PWD/deploy/cyclonedds.xml,file://$OUT/mav-control/security.xml"
#   CA keys are the crown jewels: keep OUT/ca/*.key off the robots (only the per-program dirs
#   need to be deployed).
#
# Protection (governance): --protection sets discovery/liveliness/RTPS protection and every
# topic's metadata/data protection at once (default ENCRYPT):
#   NONE     authentication + access control only (no message signing or encryption)
#   SIGN     every message authenticated (AES-GCM GMAC), nothing encrypted
#   ENCRYPT  everything encrypted and authenticated (AES-GCM)
# --rtps-protection / --metadata-protection / --data-protection override one layer afterwards
# (e.g. --protection ENCRYPT --rtps-protection NONE encrypts submessages and payloads but
# does not also protect whole RTPS messages).
# Topic rules: mav/* and everything else (*) have enable_read/write_access_control true, so a
# topic not granted in a permissions document can be neither created, written nor read.
#
# Test identities (for tests/integration/dds_security_test and checks with ddsperf, whose topics
# are DDSPerf*; each gets a grant to publish and subscribe DDSPerf* and every mav/* topic, so
# that what refuses them is their certificate, not their permissions; never deploy them):
#   --extra-test NAME     a valid identity signed by the identity CA (CN=NAME)
#   --extra-expired NAME  signed by the identity CA but valid only 2020-01-01..2020-01-02
#                         (permissions validity the same): Cyclone refuses to create a participant
#   --extra-foreign NAME  signed by a separate "foreign" identity CA made on the fly (its
#                         identity_ca.pem is that foreign CA, so it starts; governance and
#                         permissions are the real ones so only authentication differs): the
#                         real participants must refuse the handshake with it
#
# --domain ID|any  domain ids the governance and grants cover (default any = 0..230: Cyclone's
#                  access-control parser rejects ids above 230, "Can not parse governance file")
# --plugin-dir DIR directory of libdds_security_{auth,ac,crypto}.so written into security.xml
#                  (default /usr/lib/x86_64-linux-gnu/libddsc0debian, Debian's libddsc0debian)
# --days N         validity of the CAs and identities (default 365)
#
# Needs openssl (1.1.1 or 3.x) and GNU date. Exit status 0 on success, 1 on any failure (the
# message names the step and file), 2 on a usage error. Nothing is left behind on failure.
set -euo pipefail

PROG=${0##*/}
STAGE="" OUT_ABS=""
die() {  # messages name the final OUT path, not the staging directory it is built in
  local msg="$*"
  [[ -z $STAGE ]] || msg=${msg//"$STAGE"/"$OUT_ABS"}
  printf '%s: error: %s\n' "$PROG" "$msg" >&2
  exit 1
}
usage_error() { printf '%s: %s\n(see the header of %s for usage)\n' "$PROG" "$*" "$0" >&2; exit 2; }
on_err() { printf '%s: error: unexpected failure (exit %s) at line %s: %s\n' "$PROG" "$1" "$2" "$3" >&2; }
trap 'on_err $? $LINENO "$BASH_COMMAND"' ERR

# --- the access matrix -------------------------------------------------------------------------
PROGRAMS=(mav-simulator mav-localization mav-mapping mav-planning mav-control mavctl mav-load)
T_STEREO=mav/sensors/stereo
T_IMU=mav/sensors/imu
T_TRUTH=mav/sim/ground_truth
T_POSE=mav/localization/pose
T_ACT=mav/control/actuators
declare -A PUB SUB
PUB[mav-simulator]="$T_STEREO $T_IMU $T_TRUTH $T_POSE"   # pose: the contest's synthetic pose sensor
SUB[mav-simulator]="$T_ACT"
PUB[mav-localization]="$T_POSE"
SUB[mav-localization]="$T_STEREO $T_IMU"
PUB[mav-mapping]=""
SUB[mav-mapping]="$T_STEREO $T_TRUTH $T_POSE"
PUB[mav-planning]=""
SUB[mav-planning]="$T_POSE"
PUB[mav-control]="$T_ACT"                                # the only writer of actuators
SUB[mav-control]="$T_IMU $T_POSE"
PUB[mavctl]=""
SUB[mavctl]="$T_STEREO $T_IMU $T_TRUTH $T_POSE $T_ACT"
PUB[mav-load]=""                                         # may join the domain, nothing else
SUB[mav-load]=""
TEST_TOPICS="DDSPerf* mav/*"
# Grants without <partitions> cover only the default partition (the MAV stack uses no
# partitions); ddsperf answers pings through per-peer partitions, so test grants allow any.
TEST_PARTITIONS="*"

# --- arguments ---------------------------------------------------------------------------------
OUT=""
DAYS=365
FORCE=0
PROTECTION=ENCRYPT
RTPS_P="" META_P="" DATA_P=""
DOMAIN=any
PLUGIN_DIR=/usr/lib/x86_64-linux-gnu/libddsc0debian
EXTRA_TEST=() EXTRA_EXPIRED=() EXTRA_FOREIGN=()

need_arg() { [[ $# -ge 2 && -n $2 ]] || usage_error "option $1 needs a value"; }
check_kind() {
  case $2 in NONE|SIGN|ENCRYPT) ;; *) usage_error "$1 must be NONE, SIGN or ENCRYPT (got '$2')";; esac
}
while [[ $# -gt 0 ]]; do
  case $1 in
    --days) need_arg "$@"; DAYS=$2; shift 2;;
    --force) FORCE=1; shift;;
    --protection) need_arg "$@"; check_kind "$1" "$2"; PROTECTION=$2; shift 2;;
    --rtps-protection) need_arg "$@"; check_kind "$1" "$2"; RTPS_P=$2; shift 2;;
    --metadata-protection) need_arg "$@"; check_kind "$1" "$2"; META_P=$2; shift 2;;
    --data-protection) need_arg "$@"; check_kind "$1" "$2"; DATA_P=$2; shift 2;;
    --domain) need_arg "$@"; DOMAIN=$2; shift 2;;
    --plugin-dir) need_arg "$@"; PLUGIN_DIR=$2; shift 2;;
    --extra-test) need_arg "$@"; EXTRA_TEST+=("$2"); shift 2;;
    --extra-expired) need_arg "$@"; EXTRA_EXPIRED+=("$2"); shift 2;;
    --extra-foreign) need_arg "$@"; EXTRA_FOREIGN+=("$2"); shift 2;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0;;
    -*) usage_error "unknown option $1";;
    *) [[ -z $OUT ]] || usage_error "only one OUT directory may be given (got '$OUT' and '$1')"
       OUT=$1; shift;;
  esac
done
[[ -n $OUT ]] || usage_error "missing OUT directory"
[[ $DAYS =~ ^[1-9][0-9]{0,4}$ ]] || usage_error "--days must be a positive integer (got '$DAYS')"
if [[ $DOMAIN == any ]]; then DMIN=0 DMAX=230
elif [[ $DOMAIN =~ ^[0-9]+$ ]] && (( 10#$DOMAIN <= 230 )); then DMIN=$((10#$DOMAIN)) DMAX=$((10#$DOMAIN))
else usage_error "--domain must be 'any' or an id 0..230 (got '$DOMAIN')"; fi
RTPS_P=${RTPS_P:-$PROTECTION}
META_P=${META_P:-$PROTECTION}
DATA_P=${DATA_P:-$PROTECTION}
DISC_P=$PROTECTION
if [[ $PROTECTION == NONE ]]; then TOPIC_DISC_LIVE=false; else TOPIC_DISC_LIVE=true; fi

declare -A SEEN
for p in "${PROGRAMS[@]}"; do SEEN[$p]=program; done
for n in ${EXTRA_TEST[@]+"${EXTRA_TEST[@]}"} ${EXTRA_EXPIRED[@]+"${EXTRA_EXPIRED[@]}"} \
         ${EXTRA_FOREIGN[@]+"${EXTRA_FOREIGN[@]}"}; do
  [[ $n =~ ^[A-Za-z0-9][A-Za-z0-9._-]{0,62}$ ]] ||
    usage_error "identity name '$n' must be letters, digits, '.', '_' or '-'"
  [[ $n != ca ]] || usage_error "identity name 'ca' is reserved"
  [[ -z ${SEEN[$n]:-} ]] || usage_error "identity name '$n' is used twice (or is a program's)"
  SEEN[$n]=extra
done

command -v openssl >/dev/null || die "openssl not found on PATH"
date -u -d '2020-01-01 00:00:00' +%s >/dev/null 2>&1 || die "GNU date (date -d) is needed"
for lib in auth ac crypto; do
  [[ -f $PLUGIN_DIR/libdds_security_$lib.so ]] ||
    printf '%s: warning: %s not found; security.xml will name it anyway\n' \
      "$PROG" "$PLUGIN_DIR/libdds_security_$lib.so" >&2
done

# --- output directory --------------------------------------------------------------------------
MARKER=.made-by-make-certs
OUT=${OUT%/}
[[ -n $OUT ]] || die "refusing to use / as OUT"
if [[ -e $OUT || -L $OUT ]]; then
  [[ $FORCE == 1 ]] || die "$OUT already exists; pass --force to replace it"
  [[ -d $OUT && ! -L $OUT ]] || die "$OUT exists and is not a directory; not touching it"
  if [[ -n $(ls -A "$OUT") && ! -f $OUT/$MARKER ]]; then
    die "$OUT is not empty and was not made by $PROG (no $MARKER); remove it yourself"
  fi
fi
PARENT=$(dirname -- "$OUT")
[[ -d $PARENT ]] || mkdir -p -- "$PARENT" || die "cannot create parent directory $PARENT"
PARENT_ABS=$(cd -- "$PARENT" && pwd -P) || die "cannot resolve $PARENT"
OUT_ABS=$PARENT_ABS/$(basename -- "$OUT")
# These paths go into XML text and into CYCLONEDDS_URI (a comma-separated list): keep them plain.
[[ $OUT_ABS =~ ^[A-Za-z0-9/._+@=-]+$ ]] ||
  die "OUT resolves to '$OUT_ABS'; use a path of letters, digits and / . _ - + @ = only (no spaces, commas, '&' or '<')"

umask 077                # keys are born private; public files are opened up at the end
WORK=$(mktemp -d "$PARENT_ABS/.$(basename -- "$OUT").tmp.XXXXXX") ||
  die "cannot create a temporary directory in $PARENT_ABS"
cleanup() { rm -rf -- "$WORK"; }
trap cleanup EXIT
STAGE=$WORK/out          # built here, moved to OUT at the end
SCRATCH=$WORK/scratch    # openssl ca databases, CSRs
mkdir -p "$STAGE/ca" "$SCRATCH"
chmod 700 "$STAGE/ca" "$SCRATCH"
: >"$STAGE/$MARKER"

# run WHAT CMD...: run CMD, and on failure stop with "WHAT failed" plus the command's stderr.
run() {
  local what=$1 err
  shift
  if ! err=$("$@" 2>&1 >/dev/null); then
    die "$what failed: ${err:-"(no message)"}"
  fi
}

# --- openssl configuration (self-contained: the system openssl.cnf is not used) ----------------
CNF=$SCRATCH/openssl.cnf
export CA_DIR=$SCRATCH   # the [idca] section needs it set whenever openssl reads this file
cat >"$CNF" <<'EOF'
[ req ]
distinguished_name = req_dn
prompt             = no
string_mask        = utf8only
[ req_dn ]
CN = placeholder
[ ext_ca ]
basicConstraints       = critical, CA:TRUE
keyUsage               = critical, keyCertSign, cRLSign, digitalSignature
subjectKeyIdentifier   = hash
[ ext_identity ]
basicConstraints       = critical, CA:FALSE
keyUsage               = critical, digitalSignature, keyAgreement
subjectKeyIdentifier   = hash
authorityKeyIdentifier = keyid
[ ca ]
default_ca = idca
[ idca ]
dir              = $ENV::CA_DIR
database         = $dir/index.txt
new_certs_dir    = $dir/issued
rand_serial      = yes
default_md       = sha256
policy           = policy_cn
unique_subject   = no
email_in_dn      = no
copy_extensions  = none
x509_extensions  = ext_identity
[ policy_cn ]
commonName = supplied
EOF

new_key() {  # new_key FILE
  run "generating EC key $1" openssl genpkey -algorithm EC \
    -pkeyopt ec_paramgen_curve:prime256v1 -pkeyopt ec_param_enc:named_curve -out "$1"
  chmod 600 "$1"
}

new_ca() {  # new_ca BASE CN: BASE.key + BASE.pem, self-signed
  new_key "$1.key"
  run "making self-signed CA certificate $1.pem" openssl req -config "$CNF" -new -x509 \
    -key "$1.key" -subj "/CN=$2" -days "$DAYS" -sha256 -extensions ext_ca -out "$1.pem"
  mkdir -p "$SCRATCH/db-$(basename "$1")/issued"
  : >"$SCRATCH/db-$(basename "$1")/index.txt"
}

# issue CABASE NAME DIR [STARTDATE ENDDATE]: DIR/key.pem + DIR/cert.pem (CN=NAME) signed by CABASE
issue() {
  local cabase=$1 name=$2 dir=$3 csr=$SCRATCH/$2.csr
  local db=$SCRATCH/db-${1##*/}
  local validity=(-days "$DAYS")
  [[ $# -lt 5 ]] || validity=(-startdate "$4" -enddate "$5")
  mkdir -p "$dir"
  new_key "$dir/key.pem"
  run "making certificate request for $name" openssl req -config "$CNF" -new \
    -key "$dir/key.pem" -subj "/CN=$name" -out "$csr"
  run "signing $dir/cert.pem with $cabase.pem" env CA_DIR="$db" openssl ca -config "$CNF" \
    -batch -notext -cert "$cabase.pem" -keyfile "$cabase.key" -in "$csr" -out "$dir/cert.pem" \
    "${validity[@]}"
}

xml_date() {  # xml_date notBefore|notAfter CERT -> 2026-12-05T18:11:21Z
  local v
  local opt=-startdate
  [[ $1 == notBefore ]] || opt=-enddate
  v=$(openssl x509 -in "$2" -noout "$opt" 2>/dev/null) || die "reading the $1 date of $2 failed"
  v=${v#*=}
  date -u -d "$v" +%Y-%m-%dT%H:%M:%SZ 2>/dev/null || die "cannot parse date '$v' of $2"
}

smime_sign() {  # smime_sign IN OUT: signed by the permissions CA, clear-signed text S/MIME
  run "signing $2 with the permissions CA" openssl smime -sign -text \
    -signer "$STAGE/ca/permissions_ca.pem" -inkey "$STAGE/ca/permissions_ca.key" \
    -in "$1" -out "$2"
}

domains_xml() {
  printf '%s<domains><id_range><min>%s</min><max>%s</max></id_range></domains>\n' "$1" "$DMIN" "$DMAX"
}

topics_xml() {  # topics_xml INDENT publish|subscribe PARTITION TOPIC... (PARTITION "" = default only)
  local ind=$1 kind=$2 part=$3 t
  shift 3
  [[ $# -gt 0 ]] || return 0
  printf '%s<%s>\n%s  <topics>\n' "$ind" "$kind" "$ind"
  for t in "$@"; do printf '%s    <topic>%s</topic>\n' "$ind" "$t"; done
  printf '%s  </topics>\n' "$ind"
  [[ -z $part ]] || printf '%s  <partitions>\n%s    <partition>%s</partition>\n%s  </partitions>\n' \
    "$ind" "$ind" "$part" "$ind"
  printf '%s</%s>\n' "$ind" "$kind"
}

# write_permissions DIR NAME PUBTOPICS SUBTOPICS [PARTITION]
write_permissions() {
  local dir=$1 name=$2 nb na
  nb=$(xml_date notBefore "$dir/cert.pem") || exit 1
  na=$(xml_date notAfter "$dir/cert.pem") || exit 1
  # shellcheck disable=SC2086  # topic lists are space-separated words without spaces or globs
  {
    cat <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<!-- DDS Security permissions for $name, made by $PROG. Signed copy: permissions.p7s. -->
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="${name}_grant">
      <subject_name>CN=$name</subject_name>
      <validity>
        <not_before>$nb</not_before>
        <not_after>$na</not_after>
      </validity>
      <allow_rule>
$(domains_xml "        ")
$(set -f; topics_xml "        " publish "${5:-}" $3)
$(set -f; topics_xml "        " subscribe "${5:-}" $4)
      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
EOF
  } | grep -v '^$' >"$dir/permissions.xml" || die "writing $dir/permissions.xml failed"
  smime_sign "$dir/permissions.xml" "$dir/permissions.p7s"
}

# write_security_xml DIR NAME: the Cyclone <Security> fragment for identity DIR
write_security_xml() {
  local dir=$1 name=$2 final=$OUT_ABS/$2
  cat >"$dir/security.xml" <<EOF || die "writing $dir/security.xml failed"
<?xml version="1.0" encoding="UTF-8"?>
<!-- DDS Security for $name (made by $PROG). Use it together with the transport settings:
     CYCLONEDDS_URI="file:///path/to/deploy/cyclonedds.xml,file://$final/security.xml"
     Cyclone merges the listed files in order. -->
<CycloneDDS xmlns="https://cdds.io/config">
  <Domain id="any">
    <Security>
      <Authentication>
        <Library path="$PLUGIN_DIR/libdds_security_auth.so" initFunction="init_authentication" finalizeFunction="finalize_authentication"/>
        <IdentityCA>file://$final/identity_ca.pem</IdentityCA>
        <IdentityCertificate>file://$final/cert.pem</IdentityCertificate>
        <PrivateKey>file://$final/key.pem</PrivateKey>
      </Authentication>
      <AccessControl>
        <Library path="$PLUGIN_DIR/libdds_security_ac.so" initFunction="init_access_control" finalizeFunction="finalize_access_control"/>
        <PermissionsCA>file://$final/permissions_ca.pem</PermissionsCA>
        <Governance>file://$final/governance.p7s</Governance>
        <Permissions>file://$final/permissions.p7s</Permissions>
      </AccessControl>
      <Cryptographic>
        <Library path="$PLUGIN_DIR/libdds_security_crypto.so" initFunction="init_crypto" finalizeFunction="finalize_crypto"/>
      </Cryptographic>
    </Security>
  </Domain>
</CycloneDDS>
EOF
}

# finish_identity DIR NAME IDCA PUB SUB [PARTITION]: copy the shared files, write + sign the grant, config
finish_identity() {
  local dir=$1
  cp "$3" "$dir/identity_ca.pem" || die "copying $3 to $dir failed"
  cp "$STAGE/ca/permissions_ca.pem" "$dir/permissions_ca.pem" || die "copying permissions_ca.pem to $dir failed"
  cp "$STAGE/ca/governance.p7s" "$dir/governance.p7s" || die "copying governance.p7s to $dir failed"
  write_permissions "$dir" "$2" "$4" "$5" "${6:-}"
  write_security_xml "$dir" "$2"
  chmod 600 "$dir/key.pem"
}

# --- CAs and governance ------------------------------------------------------------------------
new_ca "$STAGE/ca/identity_ca" "MAV DDS Identity CA"
new_ca "$STAGE/ca/permissions_ca" "MAV DDS Permissions CA"

topic_rule() {  # topic_rule EXPRESSION
  cat <<EOF
        <topic_rule>
          <topic_expression>$1</topic_expression>
          <enable_discovery_protection>$TOPIC_DISC_LIVE</enable_discovery_protection>
          <enable_liveliness_protection>$TOPIC_DISC_LIVE</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>$META_P</metadata_protection_kind>
          <data_protection_kind>$DATA_P</data_protection_kind>
        </topic_rule>
EOF
}
GOV=$STAGE/ca/governance.xml
{
  cat <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<!-- DDS Security governance of the MAV domain, made by $PROG: protection $PROTECTION
     (rtps $RTPS_P, discovery/liveliness $DISC_P, metadata $META_P, data $DATA_P).
     Signed copy (what participants load): governance.p7s. -->
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
$(domains_xml "      ")
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>$DISC_P</discovery_protection_kind>
      <liveliness_protection_kind>$DISC_P</liveliness_protection_kind>
      <rtps_protection_kind>$RTPS_P</rtps_protection_kind>
      <topic_access_rules>
$(topic_rule 'mav/*')
$(topic_rule '*')
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
EOF
} >"$GOV" || die "writing $GOV failed"
smime_sign "$GOV" "$STAGE/ca/governance.p7s"

# --- identities --------------------------------------------------------------------------------
IDCA=$STAGE/ca/identity_ca
for p in "${PROGRAMS[@]}"; do
  issue "$IDCA" "$p" "$STAGE/$p"
  finish_identity "$STAGE/$p" "$p" "$IDCA.pem" "${PUB[$p]}" "${SUB[$p]}"
done
for n in ${EXTRA_TEST[@]+"${EXTRA_TEST[@]}"}; do
  issue "$IDCA" "$n" "$STAGE/$n"
  finish_identity "$STAGE/$n" "$n" "$IDCA.pem" "$TEST_TOPICS" "$TEST_TOPICS" "$TEST_PARTITIONS"
done
for n in ${EXTRA_EXPIRED[@]+"${EXTRA_EXPIRED[@]}"}; do
  issue "$IDCA" "$n" "$STAGE/$n" 20200101000000Z 20200102000000Z
  finish_identity "$STAGE/$n" "$n" "$IDCA.pem" "$TEST_TOPICS" "$TEST_TOPICS" "$TEST_PARTITIONS"
done
if [[ ${#EXTRA_FOREIGN[@]} -gt 0 ]]; then
  new_ca "$STAGE/ca/foreign_identity_ca" "Foreign DDS Identity CA (test only)"
  for n in "${EXTRA_FOREIGN[@]}"; do
    issue "$STAGE/ca/foreign_identity_ca" "$n" "$STAGE/$n"
    finish_identity "$STAGE/$n" "$n" "$STAGE/ca/foreign_identity_ca.pem" "$TEST_TOPICS" "$TEST_TOPICS" "$TEST_PARTITIONS"
  done
fi

# --- self-checks -------------------------------------------------------------------------------
for d in "$STAGE"/*/; do
  d=${d%/}
  [[ -f $d/cert.pem ]] || continue
  run "checking the signature on $d/permissions.p7s" openssl smime -verify -text \
    -CAfile "$d/permissions_ca.pem" -in "$d/permissions.p7s" -out /dev/null
  if command -v xmllint >/dev/null; then
    run "checking that $d/security.xml is well-formed" xmllint --noout "$d/security.xml"
    run "checking that $d/permissions.xml is well-formed" xmllint --noout "$d/permissions.xml"
  fi
done
run "checking the signature on governance.p7s" openssl smime -verify -text \
  -CAfile "$STAGE/ca/permissions_ca.pem" -in "$STAGE/ca/governance.p7s" -out /dev/null
if command -v xmllint >/dev/null; then
  run "checking that $GOV is well-formed" xmllint --noout "$GOV"
fi
for p in "${PROGRAMS[@]}" ${EXTRA_TEST[@]+"${EXTRA_TEST[@]}"}; do
  run "verifying $p/cert.pem against the identity CA" openssl verify \
    -CAfile "$STAGE/ca/identity_ca.pem" "$STAGE/$p/cert.pem"
done

# --- into place --------------------------------------------------------------------------------
# Everything is readable except the private keys (0600) and the CA directory (0700).
find "$STAGE" -mindepth 1 -maxdepth 1 -type d ! -name ca -exec chmod 755 {} + ||
  die "setting directory modes in $STAGE failed"
find "$STAGE" -mindepth 2 -type f ! -path "$STAGE/ca/*" ! -name key.pem -exec chmod 644 {} + ||
  die "setting file modes in $STAGE failed"
chmod 755 "$STAGE"
if [[ -d $OUT_ABS ]]; then
  rm -rf -- "$OUT_ABS" || die "removing the old $OUT_ABS failed"
fi
mv -- "$STAGE" "$OUT_ABS" || die "moving the result to $OUT_ABS failed"
trap - ERR
printf '%s: made %s (protection %s: rtps %s, discovery/liveliness %s, metadata %s, data %s)\n' \
  "$PROG" "$OUT_ABS" "$PROTECTION" "$RTPS_P" "$DISC_P" "$META_P" "$DATA_P"
printf '  identities:'
for d in "$OUT_ABS"/*/; do d=${d%/}; [[ ! -f $d/security.xml ]] || printf ' %s' "${d##*/}"; done
printf '\n'
