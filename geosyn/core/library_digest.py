"""Integrity of compiled libraries in the codegen cache (`geosyn.core.codegen`).

Each library ``<stem>.so`` has its sha256 stored beside it in ``<stem>.so.sha256`` when
built; `damage` compares them before the library is ever ``dlopen``-ed, so a truncated or
corrupted file (a full disk, a killed copy, a bit flip) is rebuilt instead of crashing the
process with a bus error or a segfault. A library cached before digests existed is
checked structurally (its ELF tables must lie inside the file) and adopted.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import struct
from pathlib import Path

#: Suffix of a library's digest file (``<stem>.so.sha256``).
DIGEST_SUFFIX = ".sha256"


def sha256_hex(data: bytes) -> str:
    """Hex sha256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def digest_path(library: Path) -> Path:
    """``<stem>.so.sha256``: the sha256 of the library, written beside it when built."""
    return library.with_name(library.name + DIGEST_SUFFIX)


def elf_damage(data: bytes) -> str | None:
    """Why a 64-bit little-endian ELF file is truncated or malformed, else None.

    Checks the header, then that the program headers, every segment's file bytes and the
    section header table all lie inside the file (a truncated library fails this). Other
    formats (Mach-O, 32-bit ELF) are not inspected.
    """
    if data[:4] != b"\x7fELF":
        return "not an ELF shared library"
    if len(data) < 64:
        return "truncated header"
    if data[4] != 2 or data[5] != 1:  # ELFCLASS64, ELFDATA2LSB
        return None
    phoff, shoff = struct.unpack_from("<QQ", data, 0x20)
    phentsize, phnum, shentsize, shnum = struct.unpack_from("<HHHH", data, 0x36)
    size = len(data)
    if phoff + phnum * phentsize > size or shoff + shnum * shentsize > size:
        return f"truncated: {size} bytes, its header tables end beyond"
    for i in range(phnum):
        offset, filesz = struct.unpack_from("<Q16xQ", data, phoff + i * phentsize + 8)
        if offset + filesz > size:
            return f"truncated: segment {i} ends at byte {offset + filesz} of {size}"
    return None


def damage(library: Path) -> str | None:
    """Why the cached ``library`` must not be loaded, else None.

    With its digest file: any difference from the stored sha256. Without one (a library
    cached before digests were written): the ELF structure is checked, and if intact the
    digest is written now.
    """
    try:
        data = library.read_bytes()
    except OSError as err:
        return f"unreadable: {err.strerror or err}"
    actual = sha256_hex(data)
    try:
        stored: str | None = digest_path(library).read_text().strip()
    except FileNotFoundError:
        stored = None
    except OSError as err:
        return f"its digest is unreadable: {err.strerror or err}"
    if stored is not None:
        return None if stored == actual else "sha256 differs from the digest stored beside it"
    problem = elf_damage(data)
    if problem is None:
        with contextlib.suppress(OSError):  # a read-only cache still loads
            tmp = library.with_name(f".tmp-geosyn-{os.getpid()}-{library.name}{DIGEST_SUFFIX}")
            tmp.write_text(actual + "\n")
            os.replace(tmp, digest_path(library))
    return problem


__all__ = ["DIGEST_SUFFIX", "damage", "digest_path", "elf_damage", "sha256_hex"]
