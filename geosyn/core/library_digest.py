"""Integrity of compiled libraries in the codegen cache (`geosyn.core.codegen`).

Three checks stand between a cache file and ``dlopen``:

- each library ``<stem>.so`` has its sha256 stored beside it in ``<stem>.so.sha256`` when
  built; `damage` compares them before the library is ever loaded, so a truncated or
  corrupted file (a full disk, a killed copy, a bit flip) is rebuilt instead of crashing
  the process with a bus error or a segfault. A library cached before digests existed is
  checked structurally (its ELF tables must lie inside the file) and adopted;
- each library carries its own key as an exported C string (`tagged_source`): the sha256
  of the source it was compiled from and, when a recipe asked for it, the recipe's key.
  `damage` reads them from the verified bytes and compares them with the file's name and
  with what the caller asked for, so a valid library under another library's name, or a
  recipe index naming another recipe's library, is rebuilt, never used;
- digest and recipe-index files are read defensively (`read_digest`, `read_index`): a
  short, size-capped read, ASCII only, one exact format; anything else is "corrupt" (the
  caller warns, discards and rebuilds), never a ``UnicodeDecodeError``.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import stat
import struct
from pathlib import Path

#: Suffix of a library's digest file (``<stem>.so.sha256``).
DIGEST_SUFFIX = ".sha256"
LIBRARY_TAG = "GEOSYN_LIBRARY_KEY="
"""Prefix of the string, compiled into every cached library, that holds its key."""
RECIPE_TAG = "GEOSYN_RECIPE_KEY="
"""Prefix of the string holding the key of the recipe a library was built for."""

_HEX64 = re.compile(r"[0-9a-f]{64}")
_MAX_SMALL_FILE = 4096  # bytes read of a digest or index file (they hold one line)
_TAGS = re.compile(rb"GEOSYN_(LIBRARY|RECIPE)_KEY=([0-9a-f]{64})\0")


def sha256_hex(data: bytes) -> str:
    """Hex sha256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def digest_path(library: Path) -> Path:
    """``<stem>.so.sha256``: the sha256 of the library, written beside it when built."""
    return library.with_name(library.name + DIGEST_SUFFIX)


def tagged_source(source: str, key: str, recipe_key: str | None = None) -> str:
    """``source`` with the library's key (and its recipe's) appended as exported C strings.

    Args:
        source: generated C source.
        key: 64 hex digits, the library's key (the sha256 its file name starts with).
        recipe_key: 64 hex digits of the recipe the library is built for, or None.
    """
    lines = [
        "",
        "/* geosyn codegen cache: what this library is (checked before loading it) */",
        f'const char geosyn_library_key[] = "{LIBRARY_TAG}{key}";',
    ]
    if recipe_key is not None:
        lines.append(f'const char geosyn_recipe_key[] = "{RECIPE_TAG}{recipe_key}";')
    return source + "\n".join(lines) + "\n"


def embedded_keys(data: bytes) -> tuple[list[str], list[str]]:
    """``(library keys, recipe keys)`` compiled into a library's bytes (one each, normally)."""
    found: tuple[list[str], list[str]] = ([], [])
    for kind, key in _TAGS.findall(data):
        found[0 if kind == b"LIBRARY" else 1].append(key.decode("ascii"))
    return found


def _read_small(path: Path) -> str | None:
    """The stripped ASCII text of a one-line file; None if it is not one (binary, huge).

    Raises:
        OSError: the file cannot be opened or read (FileNotFoundError when missing).
    """
    if not stat.S_ISREG(os.stat(path).st_mode):  # a FIFO would block, a device never end
        return None
    with open(path, "rb") as fh:
        raw = fh.read(_MAX_SMALL_FILE + 1)
    if len(raw) > _MAX_SMALL_FILE:
        return None
    try:
        return raw.decode("ascii").strip()
    except UnicodeDecodeError:
        return None


def read_digest(library: Path) -> str | None:
    """The sha256 stored beside ``library``: 64 hex digits, None when there is no file.

    Raises:
        ValueError: the digest file is corrupt (not 64 lowercase hex digits).
        OSError: it cannot be read.
    """
    try:
        text = _read_small(digest_path(library))
    except FileNotFoundError:
        return None
    if text is None or not _HEX64.fullmatch(text):
        raise ValueError("its digest file is corrupt (not one sha256 in hex)")
    return text


def read_index(index: Path, name: str) -> str | None:
    """The library stem a recipe index names; None when there is no index.

    Raises:
        ValueError: the index is corrupt (not ``<name>_<24 hex digits>``).
        OSError: it cannot be read.
    """
    try:
        text = _read_small(index)
    except FileNotFoundError:
        return None
    if text is None or not re.fullmatch(rf"{re.escape(name)}_[0-9a-f]{{24}}", text):
        raise ValueError(f"the recipe index {index.name} is corrupt")
    return text


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


def identity_damage(
    data: bytes, library: Path, key: str | None = None, recipe_key: str | None = None
) -> str | None:
    """Why the library bytes ``data`` are not the library asked for, else None.

    Args:
        data: the library's bytes.
        library: its path; its name ends with the first 24 hex digits of its key.
        key: the full key the caller expects (None: only the name is compared).
        recipe_key: the recipe the caller expects it to be built for (None: not checked).
    """
    keys, recipes = embedded_keys(data)
    if len(keys) != 1:
        return "it carries no geosyn library key (built by an older geosyn, or not ours)"
    name_key = library.name.removesuffix(".so").rsplit("_", 1)[-1]
    if not keys[0].startswith(name_key) or (key is not None and keys[0] != key):
        return f"it is another library (its key {keys[0][:24]} is not {name_key})"
    if recipe_key is not None and recipes != [recipe_key]:
        return "it was built for another recipe than the one asked for"
    return None


def damage(library: Path, key: str | None = None, recipe_key: str | None = None) -> str | None:
    """Why the cached ``library`` must not be loaded, else None.

    With its digest file: any difference from the stored sha256, or a corrupt digest file.
    Without one (a library cached before digests were written): the ELF structure is
    checked, and if intact the digest is written now. Then the keys compiled into it must
    match its name, ``key`` and ``recipe_key`` (`identity_damage`).

    Args:
        library: path of ``<stem>.so``.
        key: the library's full key (64 hex digits), if the caller knows it.
        recipe_key: the key of the recipe it must have been built for, if any.
    """
    try:
        if not stat.S_ISREG(os.stat(library).st_mode):
            return "not a regular file"
        data = library.read_bytes()
    except OSError as err:
        return f"unreadable: {err.strerror or err}"
    actual = sha256_hex(data)
    try:
        stored = read_digest(library)
    except ValueError as err:
        return str(err)
    except OSError as err:
        return f"its digest is unreadable: {err.strerror or err}"
    if stored is not None and stored != actual:
        return "sha256 differs from the digest stored beside it"
    problem = elf_damage(data) if stored is None else None
    problem = problem or identity_damage(data, library, key, recipe_key)
    if stored is None and problem is None:
        with contextlib.suppress(OSError):  # a read-only cache still loads
            tmp = library.with_name(f".tmp-geosyn-{os.getpid()}-{library.name}{DIGEST_SUFFIX}")
            tmp.write_text(actual + "\n")
            os.replace(tmp, digest_path(library))
    return problem


__all__ = [
    "DIGEST_SUFFIX",
    "LIBRARY_TAG",
    "RECIPE_TAG",
    "damage",
    "digest_path",
    "elf_damage",
    "embedded_keys",
    "identity_damage",
    "read_digest",
    "read_index",
    "sha256_hex",
    "tagged_source",
]
