#!/bin/sh
# Runs inside an image build (deploy/Dockerfile, deploy/Dockerfile.prebuilt): installs the
# runtime libraries of deploy/packages-runtime.txt without documentation, then adds the
# unprivileged user the services run as (uid 10001) and the data directory it owns.
set -eu
list="$1"
# Documentation, manual pages and translations are not installed (about 30 MB).
cat > /etc/dpkg/dpkg.cfg.d/01-mav-slim <<'CFG'
path-exclude /usr/share/doc/*
path-exclude /usr/share/man/*
path-exclude /usr/share/info/*
path-exclude /usr/share/locale/*
path-exclude /usr/share/lintian/*
CFG
# OpenCV's core library links the GL dispatcher (libGLX.so.0, package libglx0), and that package
# depends on Mesa's GLX vendor, which pulls the DRI drivers and LLVM: about 190 MB that no
# service loads (the dispatcher opens a vendor only when a GL context is made; the services make
# none). An empty package of that name stands in for it, so dpkg's records stay consistent.
mkdir -p /tmp/no-gl/DEBIAN
cat > /tmp/no-gl/DEBIAN/control <<CTL
Package: libglx-mesa0
Version: 99:0-mav1
Architecture: $(dpkg --print-architecture)
Maintainer: MAV stack <mav@localhost>
Description: empty stand-in for Mesa's GLX vendor library
 The MAV stack's image opens no GL context; see deploy/image-runtime.sh.
CTL
dpkg-deb --build /tmp/no-gl /tmp/no-gl.deb > /dev/null
dpkg -i /tmp/no-gl.deb > /dev/null
rm -rf /tmp/no-gl /tmp/no-gl.deb
apt-get update -q
DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends \
  $(grep -vE '^\s*(#|$)' "$list")
apt-get clean
rm -rf /var/lib/apt/lists/* /var/cache/apt/*.bin /var/log/apt /var/log/dpkg.log
useradd --system --uid 10001 --user-group --home-dir /data --no-create-home --shell /usr/sbin/nologin mav
mkdir -p /data
chown mav:mav /data
