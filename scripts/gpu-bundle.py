#!/usr/bin/env python3
"""Packs build/seasonview and the shared libraries it loads into one folder that runs on a bare machine.

Why: the GPU machine (docs/gpu.md) is a bare CUDA image that cannot install packages, and
at most 64 MiB of working tree reach it. seasonview's link closure is about 270 libraries and 350 MB,
nearly all of it pulled in by OpenImageIO's, OpenCV's and libcitygml's dependencies (ffmpeg, OpenVDB, GDAL, ICU,
...) that a benchmark run never calls. The loader wants every library of the closure before main() runs, and (the
Debian libraries here are linked BIND_NOW) every symbol they refer to.

How: libraries a run calls are copied whole; every other one is replaced by a stub with the same soname that
exports, with their versions, the symbols the binary and the kept libraries refer to and nothing else defines (all
of a window-system library's symbols, so that one the NVIDIA driver opens by name, libX11 or libwayland, still
finds its symbols): functions that abort with the library's and the symbol's name, objects of the same size in
.bss. The split was found by running the whole GPU pipeline (synth, prepare, atlas
build, bench, render) against the bundle: a stub that is called says so and aborts, and its library moves to
KEEP. glibc's own libraries stay the machine's (the GPU machine's glibc is newer than Debian 12's, which is all the
binary needs). The bundle also carries glvnd's libEGL/libOpenGL/libGLdispatch; the NVIDIA driver on the GPU machine
supplies the EGL vendor library.

Usage: scripts/gpu-bundle.py [--binary build/seasonview] [--out .gpu]
Then: LD_LIBRARY_PATH=.gpu/lib .gpu/seasonview ...   (scripts/gpu-bench.sh does this on the GPU machine)
"""
import argparse
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile

# glibc and the loader: always the machine's own.
SYSTEM = re.compile(r"^(libc|libm|libdl|libpthread|librt|libutil|libresolv|ld-linux-x86-64|libanl|libmvec)\.so")

# Libraries a run calls, found as the module docstring says (soname prefixes).
KEEP = [
    "libstdc++.so", "libgcc_s.so",
    # seasonview's own direct dependencies that every run uses
    "libOpenImageIO.so", "libOpenImageIO_Util.so", "libopencv_core.so", "libopencv_imgproc.so",
    "libtiff.so", "libgeotiff.so", "libjpeg.so", "libpng16.so", "libz.so", "libzstd.so", "libdeflate.so",
    "libGeographic", "libstb.so", "libepoxy.so", "libtinyobjloader",
    # what those call: libtiff's codecs, OpenImageIO's and OpenCV's runtime
    "liblzma.so", "libjbig.so", "libLerc.so", "libwebp.so", "libsharpyuv.so",
    "libImath", "libOpenEXR", "libIex", "libIlmThread", "libOpenColorIO.so", "libyaml-cpp.so", "libpystring",
    "libexpat.so", "libminizip.so", "libbz2.so", "libfmt.so", "libtbb.so", "libtbbmalloc.so", "libboost_",
    "libgomp.so",
    # GDAL opens every raster (core/geo/GdalSupport.cpp) and PROJ builds its CRSs from proj.db (SQLite)
    "libgdal.so", "libproj.so", "libsqlite3.so", "libjson-c.so",
    # --stream and web sources: GDAL's /vsicurl/ (Debian's GDAL and PROJ link libcurl-gnutls) and what its
    # initialisation and a plain HTTP transfer call: GnuTLS (set up when loaded) and its crypto, SSH, IDN, PSL,
    # content decoders, and LDAP, Kerberos and RTMP (curl asks them for their versions): libcurl-gnutls's closure.
    "libcurl-gnutls.so", "libgnutls.so", "libnettle.so", "libhogweed.so", "libgmp.so", "libp11-kit.so",
    "libtasn1.so", "libffi.so", "libcrypto.so", "libnghttp2.so", "libssh2.so", "libidn2.so", "libunistring.so",
    "libpsl.so", "libbrotlidec.so", "libbrotlicommon.so", "libldap-2.5.so", "liblber-2.5.so", "libsasl2.so",
    "libgssapi_krb5.so", "libkrb5.so", "libk5crypto.so", "libcom_err.so", "libkrb5support.so", "libkeyutils.so",
    "librtmp.so",
]

# Stubbed functions that run anyway and may simply return (a pointer to an empty string, for the version
# queries): what they set up or report is never used. OpenImageIO's DICOM plugin registers DCMTK's decoders at
# load, and OpenImageIO asks every format library for its version when it first lists its plugins.
SOFT = {"_ZN10DiRegisterC1Ev", "_ZN10DiRegisterD1Ev", "_ZN10DiRegisterD2Ev", "_ZN10DiRegisterC2Ev",
        "opj_version", "libraw_version", "nc_inq_libvers"}

# Loaded at run time by dlopen, not in the link closure: glvnd's EGL and GL entry points.
DLOPENED = ["libEGL.so.1", "libOpenGL.so.0", "libGLdispatch.so.0", "libGLESv2.so.2"]

PROJ_DB = "/usr/share/proj/proj.db"

# Mesa's EGL vendor library and llvmpipe's driver (--local-check).
MESA = ["/lib/x86_64-linux-gnu/libEGL_mesa.so.0", "/usr/lib/x86_64-linux-gnu/dri/swrast_dri.so"]

TRAP_C = r"""
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
__attribute__((visibility("hidden"), noreturn)) void seasonview_stub_trap(const char* symbol) {
    static const char a[] = "seasonview GPU bundle: a run called ";
    static const char b[] = " in the stub of " LIBNAME "; add it to KEEP in scripts/gpu-bundle.py\n";
    (void)!write(2, a, sizeof a - 1);
    (void)!write(2, symbol, strlen(symbol));
    (void)!write(2, b, sizeof b - 1);
    abort();
}
"""


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw).stdout


def closure(binary):
    """soname -> path of every library the binary loads (ldd); a library ldd cannot find is an error."""
    libs = {}
    for line in run(["ldd", binary]).splitlines():
        if "not found" in line:
            sys.exit(f"gpu-bundle: {binary}: {line.strip()}")
        m = re.match(r"\s*(\S+) => (\S+) \(", line)
        if m:
            libs[m.group(1)] = m.group(2)
    return libs


def soname(path):
    for line in run(["readelf", "-d", "-W", path]).splitlines():
        m = re.search(r"\(SONAME\)\s+Library soname: \[(.+)\]", line)
        if m:
            return m.group(1)
    return os.path.basename(path)


def exported(path):
    """(name, version or None, default?, type, binding, size) of every defined dynamic symbol."""
    out = []
    for line in run(["readelf", "--dyn-syms", "-W", path]).splitlines():
        f = line.split()
        if len(f) < 8 or not f[0].endswith(":") or f[6] in ("UND", "ABS") or f[4] not in ("GLOBAL", "WEAK", "UNIQUE"):
            continue
        typ, size, name = f[3], f[2], f[7]
        if typ not in ("FUNC", "IFUNC", "OBJECT", "TLS"):
            continue
        version, default = None, True
        if "@@" in name:
            name, version = name.split("@@", 1)
        elif "@" in name:
            name, version = name.split("@", 1)
            default = False
        size = int(size, 0) if not size.startswith("0x") else int(size, 16)
        out.append((name, version, default, typ, f[4], size))
    return out


def undefined(path):
    """Names of the symbols `path` needs from other libraries (versions dropped)."""
    names = set()
    for line in run(["readelf", "--dyn-syms", "-W", path]).splitlines():
        f = line.split()
        if len(f) >= 8 and f[0].endswith(":") and f[6] == "UND":
            names.add(f[7].split("@")[0])
    return names


def defined(path):
    """Names `path` defines (a stub must not take them over: the loader binds to the first definition it finds)."""
    return {s[0] for s in exported(path)}


# Defined by the linker in every shared object.
LINKER_SYMBOLS = {"_init", "_fini", "_edata", "_end", "__bss_start"}

# Stubs of window-system and DRM libraries export all of their library's symbols (less those defined elsewhere): the
# NVIDIA driver's EGL platform modules open some of them by name, and must find their symbols to load.
COMPLETE = ("libX", "libxcb", "libwayland", "libdrm", "libgbm", "libxkbcommon", "libxshmfence")


def make_stub(path, dest_dir, work, wanted, taken):
    """A stub of `path` exporting those of its symbols named in `wanted` (what the binary and the kept libraries
    refer to; stubs refer to nothing but libc), or all of them for a library named in COMPLETE, but none in `taken`
    (defined by the binary, a kept library or glibc)."""
    so = soname(path)
    if so.startswith(COMPLETE):
        wanted = None
    # One definition per name: its default version, else the first other one (a kept library referring to a
    # second, older version of the same name would not load: none does in this closure).
    chosen = {}
    for name, version, default, typ, bind, size in exported(path):
        if (wanted is not None and name not in wanted) or name in taken or name in LINKER_SYMBOLS:
            continue
        if name not in chosen or (default and not chosen[name][1]):
            chosen[name] = (version, default, typ, bind, size)
    base = so  # a base version named like the soname is what unversioned references bind to
    nodes = {}
    asm = [".text", ".p2align 4"]
    data, tls, strings = [], [], []
    for i, (name, (version, default, typ, bind, size)) in enumerate(sorted(chosen.items())):
        if version and version != base:
            nodes.setdefault(version, []).append(name)
        directive = ".weak" if bind == "WEAK" else ".globl"
        if typ in ("FUNC", "IFUNC") and name in SOFT:
            asm += [f'{directive} "{name}"', f'.type "{name}", @function', f'"{name}":',
                    "    leaq .Lempty(%rip), %rax", "    ret"]
        elif typ in ("FUNC", "IFUNC"):
            asm += [f'{directive} "{name}"', f'.type "{name}", @function', f'"{name}":',
                    f"    leaq .Lname{i}(%rip), %rdi", "    jmp seasonview_stub_trap@PLT"]
            strings += [f".Lname{i}:", f'    .asciz "{name}"']
        elif typ == "OBJECT":
            data += [f'{directive} "{name}"', f'.type "{name}", @object', f'.size "{name}", {max(size, 1)}',
                     ".p2align 4", f'"{name}":', f"    .zero {max(size, 1)}"]
        else:  # TLS
            tls += [f'{directive} "{name}"', f'.type "{name}", @tls_object', f'.size "{name}", {max(size, 1)}',
                    ".p2align 4", f'"{name}":', f"    .zero {max(size, 1)}"]
    text = "\n".join(asm + [".section .rodata", ".Lempty:", "    .asciz \"\""] + strings + [".bss"] + data +
                     ['.section .tbss,"awT",@nobits'] + tls + ['.section .note.GNU-stack,"",@progbits']) + "\n"
    versions = sorted(nodes)
    key = hashlib.sha1(so.encode()).hexdigest()[:8]
    s_file = os.path.join(work, f"stub_{key}.s")
    c_file = os.path.join(work, f"trap_{key}.c")
    v_file = os.path.join(work, f"stub_{key}.map")
    with open(s_file, "w") as f:
        f.write(text)
    with open(c_file, "w") as f:
        f.write(TRAP_C)
    with open(v_file, "w") as f:
        f.write("".join(f"{v} {{ global: " + " ".join(f'"{n}";' for n in nodes[v]) + " };\n" for v in versions))
    out = os.path.join(dest_dir, so)
    cmd = ["gcc", "-shared", "-O1", "-fPIC", f'-DLIBNAME="{so}"', "-o", out, s_file, c_file,
           f"-Wl,-soname,{so}", "-Wl,--no-undefined"]
    if versions:
        cmd.append(f"-Wl,--version-script={v_file}")
    subprocess.run(cmd, check=True)
    return so


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--binary", default="build/seasonview")
    ap.add_argument("--out", default=".gpu")
    ap.add_argument("--pack", default=".gpu-carry/bundle.tar.xz",
                    help="the bundle xz-compressed, which is what the device tool carries (the bundle itself is over "
                         "its 64 MiB; scripts/gpu-bench.sh unpacks it); '' for none")
    ap.add_argument("--local-check", action="store_true",
                    help="also keep real what Mesa's EGL and llvmpipe load (libX11, libdrm, LLVM, ...), so the bundle "
                         "runs here on llvmpipe; not for the GPU machine, whose NVIDIA EGL needs none of them")
    args = ap.parse_args()
    if not os.path.exists(args.binary):
        sys.exit(f"{args.binary}: no such binary (build first: scripts/setup.sh)")
    lib_dir = os.path.join(args.out, "lib")
    shutil.rmtree(args.out, ignore_errors=True)
    os.makedirs(lib_dir)
    shutil.copy2(args.binary, os.path.join(args.out, "seasonview"))
    every = closure(args.binary)
    libs = {so: p for so, p in every.items() if not SYSTEM.match(so)}
    for so in DLOPENED:
        if not os.path.exists(f"/lib/x86_64-linux-gnu/{so}"):
            sys.exit(f"gpu-bundle: /lib/x86_64-linux-gnu/{so} missing (Debian: libegl1, libopengl0, libgles2)")
        libs[so] = f"/lib/x86_64-linux-gnu/{so}"
    keep = {so for so in libs if so in DLOPENED or any(so.startswith(k) for k in KEEP)}
    if args.local_check:
        for mesa in MESA:
            if os.path.exists(mesa):
                for so, path in closure(mesa).items():
                    if not SYSTEM.match(so):
                        libs.setdefault(so, path)
                        keep.add(so)
    wanted = undefined(args.binary)
    taken = defined(args.binary)
    for so in keep:
        wanted |= undefined(libs[so])
        taken |= defined(libs[so])
    for so, path in every.items():
        if SYSTEM.match(so):
            taken |= defined(path)
    kept, stubbed = [], []
    with tempfile.TemporaryDirectory() as work:
        for so, path in sorted(libs.items()):
            if so in keep:
                shutil.copy2(os.path.realpath(path), os.path.join(lib_dir, so))
                kept.append(so)
            else:
                make_stub(path, lib_dir, work, wanted, taken)
                stubbed.append(so)
    # PROJ's database of CRSs (GDAL asks PROJ for the grid's CRS); scripts/gpu-bench.sh points PROJ_DATA at it.
    if os.path.exists(PROJ_DB):
        os.makedirs(os.path.join(args.out, "share", "proj"))
        shutil.copy2(PROJ_DB, os.path.join(args.out, "share", "proj", "proj.db"))
    size = sum(os.path.getsize(os.path.join(dp, f)) for dp, _, fs in os.walk(args.out) for f in fs)
    # Every library found and every symbol bound (LD_BIND_NOW), here, from the bundle.
    env = dict(os.environ, LD_LIBRARY_PATH=lib_dir, LD_BIND_NOW="1")
    check = subprocess.run([os.path.join(args.out, "seasonview"), "--help"], env=env, capture_output=True, text=True)
    if check.returncode != 0:
        sys.exit(f"gpu-bundle: {args.out}/seasonview does not start from the bundle: {check.stderr.strip()[:500]}")
    print(f"{args.out}: the binary, {len(kept)} libraries, {len(stubbed)} stubs, {size / 2**20:.1f} MiB")
    if args.pack and not args.local_check:
        os.makedirs(os.path.dirname(args.pack) or ".", exist_ok=True)
        parent, name = os.path.split(os.path.abspath(args.out))
        subprocess.run(["tar", "-cJf", os.path.abspath(args.pack), "-C", parent, name], check=True,
                       env=dict(os.environ, XZ_OPT="-9 -T2"))
        print(f"{args.pack}: {os.path.getsize(args.pack) / 2**20:.1f} MiB (carry its folder; gpu-bench.sh unpacks it)")


if __name__ == "__main__":
    main()
