#!/usr/bin/env bash
# Install test of SurfMesh's Debian package, per Debian release: builds the package
# (scripts/package.sh), installs it with apt into a CLEAN root of the release (debootstrap
# --variant=minbase: no compiler, no build packages, nothing of the repository) and checks it
# there, headless:
#   - apt installs it with its Depends and Recommends (FreeCAD, Gmsh, …) from Debian's archive;
#   - /usr/bin/surfmesh is the launcher of the workbench in /usr/share/freecad/Mod/SurfMesh;
#     `surfmesh --version` runs; freecadcmd imports SurfMesh from the system Mod folder and
#     reads its package.xml (FreeCAD.Metadata);
#   - the demo (freecadcmd <Mod>/SurfMesh/SurfMesh/cli/demo.py -- OUT): 0 tangled after both
#     optimizations, its table printed;
#   - `surfmesh optimize` on tests/data's crank arm fold (.brep + .unv): 0 tangled after;
#   - `apt-get purge` removes the workbench folder and the command.
#
#   sudo tests/package/test_package.sh                 # the host's release (bookworm)
#   sudo tests/package/test_package.sh trixie sid      # other releases, one after the other
#
# Too slow for scripts/test.sh (per release: a few minutes to build the package, the first
# time about 1 min of debootstrap and 3-4 min of apt downloading FreeCAD). As root (debootstrap,
# chroot and mounts need it); otherwise it says so and exits 77 (skipped). A package for a
# release other than the host's is built in that release's build root (scripts/debian-root.sh).
#
# Roots, kept in $SURFMESH_ROOTS_DIR (default /var/cache/surfmesh-roots), outside the repository:
#   <release>-clean        the pristine debootstrap root, made once and never changed
#   <release>-pkgtest      a fresh copy of it per run, where the package is installed
#   apt-archives-<release> apt's downloaded packages, shared by the runs (bind-mounted)
# Environment:
#   SURFMESH_ROOTS_DIR, SURFMESH_MIRROR (default http://deb.debian.org/debian)
#   SURFMESH_DEB=path      test this package instead of building one (one release only)
#   SURFMESH_KEEP_ROOT=1   keep <release>-pkgtest after the run (to look around in it)
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
ROOTS="${SURFMESH_ROOTS_DIR:-/var/cache/surfmesh-roots}"
MIRROR="${SURFMESH_MIRROR:-http://deb.debian.org/debian}"
MOD=/usr/share/freecad/Mod/SurfMesh

if [ "$(id -u)" -ne 0 ]; then
  echo "tests/package/test_package.sh: SKIPPED: needs root (debootstrap, chroot, mounts); run it with sudo"
  exit 77
fi
case "$ROOTS/" in
  "$REPO"/*) echo "test_package.sh: $ROOTS is inside the repository; choose another SURFMESH_ROOTS_DIR" >&2; exit 2 ;;
esac
command -v debootstrap >/dev/null 2>&1 || \
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q debootstrap >/dev/null

HOST="$(. /etc/os-release && echo "${VERSION_CODENAME:-unknown}")"
if [ "$#" -eq 0 ]; then set -- "$HOST"; fi
if [ -n "${SURFMESH_DEB:-}" ] && [ "$#" -gt 1 ]; then
  echo "test_package.sh: SURFMESH_DEB names one package: give one release" >&2; exit 2
fi

MOUNTS=()
unmount_all() {
  local i
  for (( i=${#MOUNTS[@]}-1; i>=0; i-- )); do umount -l "${MOUNTS[$i]}" 2>/dev/null || true; done
  MOUNTS=()
}
trap unmount_all EXIT

# remove_root DIR: only when nothing is mounted inside it, and never across file systems
remove_root() {
  local dir="$1"
  if grep -q " $dir/" /proc/mounts; then
    grep " $dir/" /proc/mounts | awk '{print $2}' | sort -r | xargs -r -n1 umount -l
  fi
  if grep -q " $dir/" /proc/mounts; then
    echo "test_package.sh: $dir still has mounts; not removing it" >&2
    return 1
  fi
  rm -rf --one-file-system "$dir"
}

SUMMARY=()
test_release() {
  local suite="$1" say t0 t_build t_root t_install t_demo t_opt deb base run archives rc
  say() { printf '[package-test %s] %s\n' "$suite" "$*"; }

  # ---- 1. the package ---------------------------------------------------------------------
  t0=$(date +%s)
  if [ -n "${SURFMESH_DEB:-}" ]; then
    deb="$(readlink -f "$SURFMESH_DEB")"
  else
    bash "$REPO/scripts/package.sh" "$suite"
    deb="$(ls "$REPO/build-package-$suite"/surfmesh_*~"${suite}"_*.deb)"
  fi
  t_build=$(( $(date +%s) - t0 ))
  say "package: $deb (${t_build} s)"

  # ---- 2. a clean root: the pristine base (made once), copied afresh ------------------------
  base="$ROOTS/$suite-clean"
  run="$ROOTS/$suite-pkgtest"
  archives="$ROOTS/apt-archives-$suite"
  t0=$(date +%s)
  if [ ! -f "$base/.surfmesh-clean-ok" ]; then
    say "making the clean root $base (debootstrap --variant=minbase $suite $MIRROR)"
    remove_root "$base"
    mkdir -p "$ROOTS"
    debootstrap --variant=minbase "$suite" "$base" "$MIRROR" >"$ROOTS/$suite-clean.log" 2>&1 \
      || { tail -20 "$ROOTS/$suite-clean.log"; say "ERROR: debootstrap failed"; return 1; }
    # no Recommends unless asked for; a mirror's Release past its Valid-Until (sid) is taken
    printf 'APT::Install-Recommends "false";\nAcquire::Check-Valid-Until "false";\n' \
      >"$base/etc/apt/apt.conf.d/99surfmesh"
    rm -f "$base"/var/cache/apt/archives/*.deb
    touch "$base/.surfmesh-clean-ok"
  fi
  remove_root "$run"
  cp -a "$base" "$run"
  t_root=$(( $(date +%s) - t0 ))
  say "clean root $run ready (${t_root} s)"

  mkdir -p "$archives/partial" "$run/proc" "$run/sys" "$run/dev/pts" "$run/dev/shm"
  mount -t proc proc "$run/proc" && MOUNTS+=("$run/proc")
  mount --bind /sys "$run/sys" && MOUNTS+=("$run/sys")
  mount --bind /dev "$run/dev" && MOUNTS+=("$run/dev")
  mount --bind /dev/pts "$run/dev/pts" && MOUNTS+=("$run/dev/pts")
  mount -t tmpfs tmpfs "$run/dev/shm" && MOUNTS+=("$run/dev/shm")
  mount --bind "$archives" "$run/var/cache/apt/archives" && MOUNTS+=("$run/var/cache/apt/archives")
  cp /etc/resolv.conf "$run/etc/resolv.conf" 2>/dev/null || true

  # only copies go in: the repository is not visible inside
  mkdir -p "$run/tmp/surfmesh-test/in"
  cp "$deb" "$run/tmp/surfmesh-test/"
  cp "$REPO/tests/data/occt_crankarm.brep" "$REPO/tests/data/occt_crankarm_fillet_fold.unv" \
     "$run/tmp/surfmesh-test/in/"
  cat >"$run/tmp/surfmesh-test/check.sh" <<'EOS'
set -euo pipefail
cd /tmp/surfmesh-test
MOD=/usr/share/freecad/Mod/SurfMesh
deb="$(ls /tmp/surfmesh-test/surfmesh_*.deb)"
step() { printf '[in root] %s\n' "$*"; }
now() { date +%s.%N; }
secs() { python3 -c "print(f'{$2 - $1:.0f}')" 2>/dev/null || echo "?"; }

if command -v cc >/dev/null 2>&1 || command -v g++ >/dev/null 2>&1 || command -v cmake >/dev/null 2>&1; then
  echo "the clean root has a compiler or CMake before the install" >&2; exit 1
fi
step "apt-get update"
apt-get update -q >apt-update.log 2>&1 || { cat apt-update.log; exit 1; }
recommends="$(dpkg-deb -f "$deb" Recommends | tr -d ',')"
step "apt-get install $(basename "$deb") and its Recommends ($recommends)"
t0=$(date +%s)
apt-get install -y -q "$deb" $recommends >apt-install.log 2>&1 || { tail -40 apt-install.log; exit 1; }
echo "T_INSTALL=$(( $(date +%s) - t0 ))"
grep -E "^(Need to get|After this operation)" apt-install.log || true
dpkg-query -W -f='installed: ${Package} ${Version}\n' surfmesh freecad python3 gmsh || true

step "the command and the workbench's files"
test -L /usr/bin/surfmesh
[ "$(readlink -f /usr/bin/surfmesh)" = "$MOD/SurfMesh/cli/launcher.py" ]
ls "$MOD"/SurfMesh/_surfmesh*.so "$MOD/package.xml" "$MOD/InitGui.py" >/dev/null
# Nothing is compiled here (the root had no compiler, see above). Debian's own FreeCAD stack may
# bring one (bookworm: python3-matplotlib -> python3-scipy -> python3-pythran -> g++).
ver="$(cd / && surfmesh --version)"
echo "$ver"
case "$ver" in "surfmesh "*"$MOD/SurfMesh)") ;; *) echo "unexpected --version output" >&2; exit 1 ;; esac

step "freecadcmd finds the workbench in FreeCAD's system Mod folder and reads its package.xml"
cat >fc_check.py <<'EOP'
import os, sys
import FreeCAD
import SurfMesh
here = os.path.realpath(os.path.dirname(SurfMesh.__file__))
assert here == "/usr/share/freecad/Mod/SurfMesh/SurfMesh", here
md = FreeCAD.Metadata("/usr/share/freecad/Mod/SurfMesh/package.xml")
assert md.Name == "SurfMesh", md.Name
assert md.Version == SurfMesh.__version__, (md.Version, SurfMesh.__version__)
kinds = sorted(u["type"] for u in md.Urls)
assert "repository" in kinds and "bugtracker" in kinds, kinds
deps = sorted(d["package"] for d in md.Depend)
assert {"fem", "mesh", "part"} <= set(deps), deps
assert [c.Classname for c in md.Content["workbench"]] == ["SurfMeshWorkbench"]
with open("/tmp/surfmesh-test/fc_check.ok", "w") as fh:
    fh.write(f"SurfMesh {SurfMesh.__version__} from {here}; FreeCAD {'.'.join(FreeCAD.Version()[:3])}, "
             f"Python {sys.version.split()[0]}; package.xml: depends {deps}, urls {kinds}\n")
EOP
rm -f fc_check.ok
freecadcmd fc_check.py >fc_check.log 2>&1 || true
[ -f fc_check.ok ] || { cat fc_check.log; echo "freecadcmd check failed" >&2; exit 1; }
cat fc_check.ok

step "the demo, headless: freecadcmd $MOD/SurfMesh/cli/demo.py -- /tmp/surfmesh-test/demo"
t0=$(date +%s)
freecadcmd "$MOD/SurfMesh/cli/demo.py" -- /tmp/surfmesh-test/demo >demo.log 2>&1 || true
echo "T_DEMO=$(( $(date +%s) - t0 ))"
[ -f demo/table.txt ] && [ -f demo/report.json ] || { tail -40 demo.log; echo "the demo failed" >&2; exit 1; }
cat demo/table.txt
python3 - <<'EOP'
import json
r = json.load(open("/tmp/surfmesh-test/demo/report.json"))
for m, run in r["runs"].items():
    b, a = run["before"]["tangled"], run["after"]["tangled"]
    print(f"demo {m}: {b} tangled before, {a} after; after: min {run['after']['min']:.3f}, "
          f"mean {run['after']['mean']:.3f}")
    assert b > 0 and a == 0, (m, b, a)
EOP

step "surfmesh optimize on the crank arm's fold (.brep + .unv)"
t0=$(date +%s)
surfmesh optimize in/occt_crankarm.brep in/occt_crankarm_fillet_fold.unv -o out.unv \
  --measure oddy --report opt.json
echo "T_OPT=$(( $(date +%s) - t0 ))"
python3 - <<'EOP'
import json, os
r = json.load(open("/tmp/surfmesh-test/opt.json"))
b, a = r["before"]["tangled"], r["after"]["tangled"]
print(f"surfmesh optimize: {b} tangled before, {a} after")
assert b > 0 and a == 0 and os.path.getsize("/tmp/surfmesh-test/out.unv") > 0, (b, a)
EOP

step "apt-get purge surfmesh removes the workbench and the command"
apt-get purge -y -q surfmesh >apt-purge.log 2>&1 || { cat apt-purge.log; exit 1; }
[ ! -e "$MOD" ] && [ ! -e /usr/bin/surfmesh ] || { ls -R "$MOD" | head; echo "left behind" >&2; exit 1; }
echo "purged: nothing left"
echo "PACKAGE TEST OK"
EOS
  say "installing and checking in the clean root"
  rc=0
  chroot "$run" /usr/bin/env -i HOME=/root LANG=C.UTF-8 DEBIAN_FRONTEND=noninteractive \
    PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
    /bin/bash /tmp/surfmesh-test/check.sh 2>&1 | tee "$ROOTS/$suite-pkgtest.log" || rc=$?
  grep -q "^PACKAGE TEST OK" "$ROOTS/$suite-pkgtest.log" || rc=1
  t_install="$(sed -n 's/^T_INSTALL=//p' "$ROOTS/$suite-pkgtest.log")"
  t_demo="$(sed -n 's/^T_DEMO=//p' "$ROOTS/$suite-pkgtest.log")"
  t_opt="$(sed -n 's/^T_OPT=//p' "$ROOTS/$suite-pkgtest.log")"
  unmount_all
  if [ "${SURFMESH_KEEP_ROOT:-0}" != "1" ]; then remove_root "$run"; fi
  local verdict=PASSED
  [ "$rc" -eq 0 ] || verdict=FAILED
  SUMMARY+=("$suite: $verdict — package ${t_build} s, clean root ${t_root} s, apt install ${t_install:-?} s, demo ${t_demo:-?} s, surfmesh optimize ${t_opt:-?} s ($(basename "$deb"); log $ROOTS/$suite-pkgtest.log)")
  return "$rc"
}

status=0
for suite in "$@"; do
  test_release "$suite" || status=1
done
echo
echo "== package test =="
printf '%s\n' "${SUMMARY[@]}"
exit "$status"
