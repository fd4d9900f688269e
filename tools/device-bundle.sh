#!/usr/bin/env bash
# Packs BUILD_DIR/flockmorph, every shared library it needs but glibc's, and a relocatable Open MPI
# 4.1 runtime (Debian 12's packages, unpacked with dpkg -x) into .devbundle/bundle.tar.xz, so that
# `mpirun -np 16 flockmorph ...` runs on a bare x86-64 machine (glibc >= 2.36) without installing
# anything (tools/bench-scaling.sh). On that machine:
#   mkdir DIR && tar -xJf bundle.tar.xz -C DIR && source DIR/env.sh
# The tarball holds bin/flockmorph, lib/ (the libraries), mpi/ (mpirun, its MCA plugins, PMIx's,
# help texts, the MCA parameter files) and env.sh. Run on Debian 12 as root (apt-get download);
# waits up to 20 min for BUILD_DIR/flockmorph to exist when a build is still running.
#   tools/device-bundle.sh [BUILD_DIR]      default BUILD_DIR: build
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
cli=$build/flockmorph
say() { echo "device-bundle: $*" >&2; }

waited=0
until [ -x "$cli" ]; do
  [ "$waited" -ge 1200 ] && { say "no $cli after 20 min (build first: tools/setup.sh $build)"; exit 1; }
  say "waiting for $cli (a build running?)"
  sleep 30
  waited=$((waited + 30))
done
# The linker may still be writing it: wait until its size stays put.
size=-1
while [ "$size" != "$(stat -c %s "$cli")" ]; do size=$(stat -c %s "$cli"); sleep 3; done

out=.devbundle
mkdir -p "$out"
if [ -d .git ] && [ -f .git/info/exclude ]; then
  grep -qx '/.devbundle/' .git/info/exclude || echo /.devbundle/ >> .git/info/exclude
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
chmod 755 "$tmp" # apt-get download drops to user _apt, which must reach the folder
root=$tmp/root    # the packages, unpacked
b=$tmp/bundle     # what goes in the tarball
mkdir -p "$tmp/debs" "$root" "$b/bin" "$b/lib" "$b/mpi"

# Open MPI and what mpirun, libmpi and the MCA plugins kept below need besides glibc.
debs=(openmpi-bin openmpi-common libopenmpi3 libpmix2 libhwloc15 libevent-core-2.1-7
  libevent-pthreads-2.1-7 libmunge2 libnl-3-200 libudev1 zlib1g)
say "apt-get download ${debs[*]}"
(cd "$tmp/debs" && apt-get download -qq "${debs[@]}" 2>&1 | { grep -v 'unsandboxed as root' || true; } >&2)
for d in "$tmp"/debs/*.deb; do dpkg -x "$d" "$root"; done
ml=$root/usr/lib/x86_64-linux-gnu
plugins=$ml/openmpi/lib/openmpi3
pmixdir=$ml/pmix2
if [ ! -x "$root/usr/bin/orterun" ] || [ ! -d "$plugins" ] || [ ! -d "$pmixdir/lib/pmix" ]; then
  say "unexpected layout of Debian's Open MPI packages"; exit 1
fi

# Prune: the fabric plugins (UCX, libfabric, PSM, verbs: no such hardware, and a single node uses
# the shared-memory BTL vader), OpenSHMEM, Fortran, Java, compiler wrappers, docs.
rm -f "$plugins"/*_ucx.so "$plugins"/*_ofi.so "$plugins"/mca_mtl_psm*.so "$plugins"/mca_btl_openib.so \
  "$plugins"/mca_atomic_*.so "$plugins"/mca_memheap_*.so "$plugins"/mca_scoll_*.so \
  "$plugins"/mca_spml_*.so "$plugins"/mca_sshmem_*.so
rm -f "$ml"/libmca_common_{ucx,ofi,verbs}.so* "$ml"/liboshmem.so* "$ml"/libmpi_java.so* \
  "$ml"/libmpi_mpifh* "$ml"/libmpi_usempi* "$ml"/openmpi/lib/*.so
rm -rf "$root/usr/share/doc" "$root/usr/share/man" "$root/usr/share/lintian" "$ml/openmpi/include"
find "$root/usr/bin" -mindepth 1 -maxdepth 1 \
  ! -name orterun ! -name orted ! -name ompi_info ! -name orte-info -exec rm -f {} +
ln -s orterun "$root/usr/bin/mpirun"
ln -s orterun "$root/usr/bin/mpiexec"

# The packages' shared libraries go to lib/ (one folder on LD_LIBRARY_PATH), not in the MPI tree.
mkdir -p "$tmp/mpilibs"
for d in "$ml" "$root/lib/x86_64-linux-gnu"; do
  if [ -d "$d" ]; then find "$d" -maxdepth 1 -name 'lib*.so*' -exec mv {} "$tmp/mpilibs/" \;; fi
done
rm -f "$pmixdir"/lib/lib*.so*
cp "$cli" "$b/bin/flockmorph"
cp -a "$root/usr" "$root/etc" "$b/mpi/"
ml=$b/mpi/usr/lib/x86_64-linux-gnu plugins=$ml/openmpi/lib/openmpi3 pmixdir=$ml/pmix2

# Every library in the ldd closure of flockmorph, mpirun, orted, ompi_info and the plugins but
# glibc's: the MPI ones from the packages (found first), the others from this machine.
glibc='^(libc\.so|libm\.so|libpthread\.so|libdl\.so|librt\.so|libresolv\.so|libutil\.so|ld-linux|libmvec\.so|libanl\.so|libnsl\.so\.1|libBrokenLocale\.so|libthread_db\.so|linux-vdso)'
elfs=("$b/bin/flockmorph" "$b/mpi/usr/bin/orterun" "$b/mpi/usr/bin/orted" "$b/mpi/usr/bin/ompi_info"
  "$b/mpi/usr/bin/orte-info" "$plugins"/*.so "$pmixdir"/lib/pmix/*.so)
bad=0
for f in "${elfs[@]}"; do
  while read -r name arrow path _; do
    [ "$arrow" = "=>" ] || continue
    [[ $name =~ $glibc ]] && continue
    if [ "$path" = not ]; then say "$f: $name not found"; bad=1; continue; fi
    [ -e "$b/lib/$name" ] || cp -L "$path" "$b/lib/$name"
  done < <(LD_LIBRARY_PATH=$tmp/mpilibs ldd "$f")
done
[ "$bad" = 0 ] || exit 1

cat > "$b/env.sh" <<'EOF'
# Source after extracting bundle.tar.xz to DIR (tools/device-bundle.sh): flockmorph and Open MPI
# 4.1 (Debian 12's) from DIR, nothing from the system but glibc.
fm_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
export PATH=$fm_dir/bin:$fm_dir/mpi/usr/bin:$PATH
export LD_LIBRARY_PATH=$fm_dir/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
# Open MPI relocates what Debian configured under ${prefix} (libdir, the plugins' pkglibdir,
# pkgdatadir with the help texts: ompi_info --path all); sysconfdir (/etc/openmpi, with Debian's
# openmpi-mca-params.conf) is absolute, so it is set too.
export OPAL_PREFIX=$fm_dir/mpi/usr
export OPAL_SYSCONFDIR=$fm_dir/mpi/etc/openmpi
# PMIx 4.2 (external to Open MPI) was configured with absolute paths under
# /usr/lib/x86_64-linux-gnu/pmix2, and its pmix-mca-params.conf names the plugin folder absolutely.
fm_pmix=$fm_dir/mpi/usr/lib/x86_64-linux-gnu/pmix2
export PMIX_PREFIX=$fm_pmix PMIX_EXEC_PREFIX=$fm_pmix
export PMIX_LIBDIR=$fm_pmix/lib PMIX_PKGLIBDIR=$fm_pmix/lib/pmix
export PMIX_DATADIR=$fm_pmix/share PMIX_PKGDATADIR=$fm_pmix/share/pmix PMIX_SYSCONFDIR=$fm_pmix/share
export PMIX_MCA_mca_base_component_path=$fm_pmix/lib/pmix
# hwloc (topology) needs none of its plugins; a folder that does not exist keeps it off a system's.
export HWLOC_PLUGINS_PATH=$fm_dir/mpi/no-hwloc-plugins
# One node, as root, no ssh: shared memory only (no UCX/libfabric), local launch, any rank count.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_btl=self,vader OMPI_MCA_pml=ob1 OMPI_MCA_plm=isolated
export OMPI_MCA_rmaps_base_oversubscribe=1
# vader keeps 4 MiB a rank in /dev/shm; a container's is often 64 MiB: then /tmp instead.
if [ "$(df -Pk /dev/shm 2>/dev/null | awk 'NR == 2 { print $4 }')" -lt 524288 ] 2>/dev/null \
  || [ ! -d /dev/shm ]; then
  export OMPI_MCA_btl_vader_backing_directory=/tmp
fi
# vader copies large messages once with CMA (process_vm_readv); where a container forbids it, ranks
# fail with "Read -1, expected N, errno = 1": export OMPI_MCA_btl_vader_single_copy_mechanism=none
# (tools/bench-scaling.sh finds out by itself).
unset fm_pmix
EOF

say "packing $out/bundle.tar.xz ($(du -sh "$b" | cut -f1) unpacked)"
tar -C "$b" --owner=0 --group=0 -cf - . | xz -9 -T2 > "$out/bundle.tar.xz.part"
mv "$out/bundle.tar.xz.part" "$out/bundle.tar.xz"
say "$out/bundle.tar.xz: $(du -h "$out/bundle.tar.xz" | cut -f1), $(find "$b/lib" -type f | wc -l) libraries"
