#!/usr/bin/env bash
# Builds the holodeck image from Containerfile on a host that reaches a Debian
# mirror and crates.io but no container registry (its base images come from
# deploy/offline-bases.sh), then runs it: a build step on top of the image,
# as its own user, prints the version, fills a file with the built-in room,
# reads it back with info and draws it with the mesh driver on the image's
# software Vulkan. A build step stands in for `podman run`, which needs
# cgroups that a build host inside a container may not have.
#
# Usage (as root; needs podman and debootstrap):
#   deploy/build-image.sh [TAG] [DEBIAN MIRROR]
# PODMAN_OPTS adds options to every `podman build`; EXTRA_CA names extra
# certificate authorities for cargo (see deploy/offline-bases.sh).
set -euo pipefail
TAG=${1:-holodeck}
MIRROR=${2:-http://deb.debian.org/debian}
PODMAN_OPTS=${PODMAN_OPTS:-}
here=$(cd "$(dirname "$0")/.." && pwd)

"$here/deploy/offline-bases.sh" "$MIRROR"

start=$(date +%s)
# shellcheck disable=SC2086 # PODMAN_OPTS is a list of options
podman build --isolation chroot $PODMAN_OPTS -t "$TAG" -f "$here/Containerfile" "$here"
size=$(podman image inspect --format '{{.Size}}' "$TAG")
echo "build-image: $TAG built in $(($(date +%s) - start)) s: $((size / 1000000)) MB"

smoke=$(mktemp -d)
trap 'rm -rf "$smoke"' EXIT
cat >"$smoke/Containerfile" <<EOF
FROM $TAG
RUN test "\$(id -u)" = 10001 \\
    && holodeck --version \\
    && holodeck fill builtin:room /data/room.hdk --rays 100K \\
    && holodeck info /data/room.hdk \\
    && holodeck pict /data/room.hdk --driver mesh -x 64 -y 48 -o /data/room.png \\
    && test -s /data/room.png \\
    && test "\$(stat -c %u /data/room.hdk)" = 10001
EOF
# shellcheck disable=SC2086 # PODMAN_OPTS is a list of options
podman build --isolation chroot $PODMAN_OPTS -t "$TAG-smoke" "$smoke"
podman rmi "$TAG-smoke" >/dev/null
echo "build-image: $TAG runs: version, fill, info and pict as uid 10001"
