"""The checksum of an output file's texts (docs/output.md, Checksums), for every script that reads
run files or study indexes.

HDF5 keeps the characters of variable-length strings (text attributes such as `status`,
`namelist`, `columns`, and the column-name datasets) in its global heap, which has no checksum of
its own: a damaged byte there reads as another text. eme_run and eme_ensemble store the CRC-32 of
every such text in the root attribute `text_checksum`; `check_texts` computes it again from the
file as documented and raises DamagedFileError when it differs. A file written before the
attribute existed has none and is taken as it is.
"""
import zlib

import h5py
import numpy as np

CHECKSUM_ATTRIBUTE = "text_checksum"
_RAW = h5py.string_dtype("ascii")       # variable-length strings read as their bytes, undecoded


class DamagedFileError(OSError):
    """A text of the file is not the one its text_checksum was computed from."""


def _is_text(dtype):
    info = h5py.check_string_dtype(dtype)
    return info is not None and info.length is None


def _raw_texts(read, shape):
    """The bytes of each variable-length string an HDF5 read gives, as a flat list."""
    values = np.empty(shape, dtype=_RAW)
    read(values, h5py.h5t.py_create(_RAW))
    return [value or b"" for value in values.ravel()]


def _record(object_name, name, texts):
    return (object_name.encode() + b"\0" + name.encode() + b"\0" + b"".join(text + b"\0" for text in texts)
            + b"\x1e")


def _object_records(object_name, item):
    """The records of one object: its text attributes by name, then a text dataset's values."""
    for name in sorted(item.attrs, key=lambda text: text.encode()):
        attribute = h5py.h5a.open(item.id, name.encode())
        if _is_text(attribute.dtype):
            yield _record(object_name, name, _raw_texts(attribute.read, attribute.shape))
    if isinstance(item, h5py.Dataset) and _is_text(item.dtype):
        yield _record(object_name, "", _raw_texts(lambda out, mtype: item.id.read(h5py.h5s.ALL, h5py.h5s.ALL, out,
                                                                                  mtype), item.shape))


def text_checksum(handle):
    """The CRC-32 of the texts of an open file: the root group's ("/"), then each object of the
    root group's by name, as src/io/hdf5_text_checksum.c computes it. An object that cannot be
    opened raises (h5py's KeyError or OSError; its items() would give None for it)."""
    crc = 0
    for name in ["/", *sorted(handle, key=lambda text: text.encode())]:
        for record in _object_records(name, handle if name == "/" else handle[name]):
            crc = zlib.crc32(record, crc)
    return crc


def seal_texts(handle):
    """Writes text_checksum of a file open for writing whose texts were changed on purpose (a tool
    that edits run files with h5py): without it, the readers take the file for damaged."""
    handle.attrs.create(CHECKSUM_ATTRIBUTE, text_checksum(handle), dtype=np.uint32)


def check_texts(handle, path):
    """Raises DamagedFileError naming `path` if the open file's texts fail their checksum, or if
    one of its objects or texts cannot be read (a damaged object header)."""
    try:
        if CHECKSUM_ATTRIBUTE not in handle.attrs:
            return
        stored = int(handle.attrs[CHECKSUM_ATTRIBUTE])
        computed = text_checksum(handle)
    except (OSError, KeyError, RuntimeError, ValueError) as error:
        raise DamagedFileError(f"{path}: an object or a text of the file cannot be read ({error}): "
                               "the file is damaged") from None
    if computed != stored:
        raise DamagedFileError(f"{path}: a text of the file fails its checksum ({CHECKSUM_ATTRIBUTE}): "
                               "the file is damaged")
