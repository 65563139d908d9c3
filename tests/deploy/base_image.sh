#!/usr/bin/env bash
# Makes the base image the Containerfile names (debian:bookworm-slim) from Debian's own mirror
# with debootstrap, for machines that reach no container registry (this CI). The mirror is the
# one apt already uses here. A machine that can pull images never needs this.
set -euo pipefail
image=docker.io/library/debian:bookworm-slim
if podman image exists "$image"; then exit 0; fi
mirror=$(awk '/^URIs:/{print $2; exit}' /etc/apt/sources.list.d/debian.sources 2>/dev/null || true)
[[ -n "$mirror" ]] || mirror=$(awk '$1 == "deb" {print $2; exit}' /etc/apt/sources.list)
rootfs=$(mktemp -d)
trap 'rm -rf "$rootfs"' EXIT
debootstrap --variant=minbase bookworm "$rootfs" "$mirror" >/dev/null
tar -C "$rootfs" -c . | podman import - "$image" >/dev/null
echo "made $image from $mirror"
