#!/usr/bin/env bash
# Makes the two base images that Containerfile starts from, for build hosts
# that reach a Debian mirror and crates.io but no container registry (a
# cluster's build node behind a mirror-only firewall):
#   docker.io/library/debian:bookworm-slim  from debootstrap (minbase)
#   docker.io/library/rust:<version>-bookworm  that Debian with a C and C++
#       compiler and this host's Rust toolchain (rustup, its default toolchain
#       with the wasm32-unknown-unknown target) copied in
# Both are tagged with the names Containerfile uses, so that `podman build`
# then finds them locally and pulls nothing. Certificate authorities named in
# EXTRA_CA (space-separated .crt files: a proxy that inspects TLS) are trusted
# in the Rust image, so that cargo can fetch crates through the proxy.
#
# Usage (as root; needs podman and debootstrap):
#   deploy/offline-bases.sh [DEBIAN MIRROR]
#   podman build -t holodeck -f Containerfile .
# Build steps run with chroot isolation, which works where containers cannot
# create cgroups (a build host that is itself a container); PODMAN_OPTS adds
# options to `podman build` (for example --ulimit nofile=1024:1024 where the
# host's limits are lower than podman's defaults).
set -euo pipefail
MIRROR=${1:-http://deb.debian.org/debian}
PODMAN_OPTS=${PODMAN_OPTS:-}
here=$(cd "$(dirname "$0")/.." && pwd)
rust_image=$(sed -n 's/^FROM \(docker.io\/library\/rust:[^ ]*\) AS build$/\1/p' "$here/Containerfile")
debian_image=$(sed -n 's/^FROM \(docker.io\/library\/debian:[^ ]*\)$/\1/p' "$here/Containerfile")
[ -n "$rust_image" ] && [ -n "$debian_image" ] || {
  echo "offline-bases: Containerfile names no rust and debian images" >&2
  exit 1
}
sysroot=$(rustc --print sysroot)
toolchain=$(basename "$sysroot")
if ! rustup target list --installed | grep -qx wasm32-unknown-unknown; then
  echo "offline-bases: the toolchain $toolchain lacks wasm32-unknown-unknown (rustup target add it first)" >&2
  exit 1
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "offline-bases: $debian_image from $MIRROR"
debootstrap --variant=minbase bookworm "$work/rootfs" "$MIRROR" >"$work/debootstrap.log"
tar -C "$work/rootfs" -c . | podman import - "$debian_image" >/dev/null
rm -rf "$work/rootfs"

echo "offline-bases: $rust_image with $toolchain ($(rustc --version))"
ctx="$work/rust"
mkdir -p "$ctx/rustup/toolchains" "$ctx/cargo/bin" "$ctx/ca"
cp -a "$sysroot" "$ctx/rustup/toolchains/"
rm -rf "$ctx/rustup/toolchains/$toolchain/share/doc"
printf 'version = "12"\ndefault_toolchain = "%s"\nprofile = "minimal"\n' "$toolchain" >"$ctx/rustup/settings.toml"
for b in cargo rustc rustdoc rustup; do
  cp "$(command -v rustup)" "$ctx/cargo/bin/$b"
done
for ca in ${EXTRA_CA:-}; do
  cp "$ca" "$ctx/ca/"
done
cat >"$ctx/Containerfile" <<EOF
FROM $debian_image
RUN apt-get update \\
    && apt-get install -y --no-install-recommends ca-certificates gcc g++ libc6-dev make pkg-config \\
    && rm -rf /var/lib/apt/lists/*
COPY ca/ /usr/local/share/ca-certificates/
RUN update-ca-certificates
ENV RUSTUP_HOME=/usr/local/rustup CARGO_HOME=/usr/local/cargo \\
    PATH=/usr/local/cargo/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
COPY rustup /usr/local/rustup
COPY cargo /usr/local/cargo
EOF
# shellcheck disable=SC2086 # PODMAN_OPTS is a list of options
podman build --isolation chroot $PODMAN_OPTS -t "$rust_image" "$ctx" >"$work/build.log" || {
  cat "$work/build.log" >&2
  exit 1
}
echo "offline-bases: done; now: podman build --isolation chroot $PODMAN_OPTS -t holodeck -f Containerfile ."
