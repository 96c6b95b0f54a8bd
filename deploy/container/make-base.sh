#!/usr/bin/env bash
# Builds the container base image, Debian bookworm (minbase), with debootstrap from the mirror this
# machine's apt uses, and imports it into podman. No registry is contacted: only the Debian mirror.
#   deploy/container/make-base.sh [--force] [--tag IMAGE]
# The image defaults to localhost/bistable-base:bookworm ($BISTABLE_BASE_IMAGE); it is kept once built
# (--force rebuilds it). Its /etc/apt/sources.list lists every bookworm suite apt uses here
# (bookworm, bookworm-updates, bookworm-security, ...), so the image gets the same packages as the host.
# Needs root (debootstrap), debootstrap and podman; about 30 s and 130 MB here.
set -euo pipefail

suite=bookworm
image=${BISTABLE_BASE_IMAGE:-localhost/bistable-base:bookworm}
force=0
while [ "$#" -gt 0 ]; do
  case "$1" in
    --force) force=1 ;;
    --tag) shift; image=${1:?--tag needs an image name} ;;
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    *) echo "make-base: unknown argument: $1" >&2; exit 2 ;;
  esac
  shift
done

if [ "$force" -eq 0 ] && podman image exists "$image"; then
  echo "make-base: $image exists (--force rebuilds it)"
  exit 0
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "make-base: debootstrap needs root" >&2
  exit 1
fi
command -v debootstrap >/dev/null || { echo "make-base: debootstrap is not installed" >&2; exit 1; }

# The mirror and suites come from apt's own view of its sources (deb822 or one-line, any file).
# shellcheck disable=SC2016  # apt-get expands $(FIELD) itself
format='$(REPO_URI)|$(RELEASE)|$(COMPONENT)'
mirror=""
comps=()
sources=""
while IFS='|' read -r uri release component; do
  case "$release" in
    "$suite") mirror=${uri%/}; comps+=("$component") ;;
    "$suite"-*) ;;
    *) continue ;;
  esac
  sources="${sources}deb ${uri%/} $release $component"$'\n'
done < <(apt-get indextargets --format "$format" "Identifier: Packages" "Target-Of: deb" | sort -u)
if [ -z "$mirror" ]; then
  echo "make-base: apt has no source for suite $suite (apt-get indextargets lists none)" >&2
  exit 1
fi
components=$(printf '%s\n' "${comps[@]}" | sort -u | paste -sd, -)
keyring=/usr/share/keyrings/debian-archive-keyring.gpg

work=$(mktemp -d /var/tmp/bistable-base.XXXXXX)
root="$work/rootfs"
cleanup() {
  # debootstrap mounts /proc and /sys in the target; never delete through a mount.
  if [ -d "$root" ]; then
    awk -v r="$root" 'index($2, r) == 1 { print $2 }' /proc/self/mounts | sort -r |
      while read -r m; do umount -l "$m" || true; done
  fi
  rm -rf --one-file-system "$work"
}
trap cleanup EXIT

echo "make-base: debootstrap --variant=minbase $suite from $mirror (components $components)"
start=$(date +%s)
debootstrap --variant=minbase --components="$components" --keyring="$keyring" \
  "$suite" "$root" "$mirror" > "$work/debootstrap.log" 2>&1 || {
  echo "make-base: debootstrap failed; the end of its log:" >&2
  tail -n 30 "$work/debootstrap.log" >&2
  if [ -f "$root/debootstrap/debootstrap.log" ]; then tail -n 30 "$root/debootstrap/debootstrap.log" >&2; fi
  exit 1
}

# Container conventions: the host's suites, no daemons started by package scripts, no recommends,
# no documentation (copyright files stay), nothing of this host (resolv.conf, hostname, machine-id).
printf '%s' "$sources" > "$root/etc/apt/sources.list"
printf '#!/bin/sh\n# containers start no services while packages are installed\nexit 101\n' > "$root/usr/sbin/policy-rc.d"
chmod 755 "$root/usr/sbin/policy-rc.d"
cat > "$root/etc/apt/apt.conf.d/90container" <<'EOF'
APT::Install-Recommends "false";
APT::Install-Suggests "false";
Acquire::Languages "none";
EOF
cat > "$root/etc/dpkg/dpkg.cfg.d/90container-nodoc" <<'EOF'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/info/*
path-exclude /usr/share/locale/*
path-include /usr/share/locale/locale.alias
path-exclude /usr/share/lintian/*
EOF
# ... and the same for what debootstrap installed (about 45 MB); only ever inside the new root.
case "$root" in
  /var/tmp/bistable-base.*/rootfs) ;;
  *) echo "make-base: refusing to trim '$root'" >&2; exit 1 ;;
esac
find "$root/usr/share/doc" -mindepth 1 ! -type d ! -name copyright -delete
find "$root/usr/share/doc" -mindepth 1 -type d -empty -delete
find "$root/usr/share/man" "$root/usr/share/info" "$root/usr/share/lintian" "$root/usr/share/locale" -mindepth 1 \
  -maxdepth 1 ! -name locale.alias -exec rm -rf -- {} + 2>/dev/null || true
chroot "$root" apt-get clean
rm -rf "$root"/var/lib/apt/lists/* "$root"/var/cache/apt/*.bin "$root"/var/log/*.log "$root"/var/log/apt/* \
       "$root/etc/resolv.conf" "$root/etc/hostname" "$root/debootstrap"
: > "$root/etc/machine-id"

echo "make-base: importing as $image"
tar --numeric-owner --xattrs -C "$root" --exclude='./dev/*' --exclude='./proc/*' --exclude='./sys/*' \
  -cf "$work/rootfs.tar" .
podman import --quiet \
  --change 'ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
  --change 'ENV LANG=C.UTF-8' \
  --change 'CMD ["/bin/bash"]' \
  --change "LABEL org.opencontainers.image.title=bistable-base org.opencontainers.image.description=debootstrap-minbase-$suite bistable.base.mirror=$mirror bistable.base.suite=$suite" \
  --message "debootstrap --variant=minbase $suite $mirror" \
  "$work/rootfs.tar" "$image" >/dev/null
echo "make-base: $image built in $(( $(date +%s) - start )) s ($(podman image inspect --format '{{.Size}}' "$image") bytes)"
