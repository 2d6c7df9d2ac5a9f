"""A recording's members, opened only where their bytes are in the recording itself.

HDF5 lets a name point elsewhere and a dataset keep its bytes elsewhere: an external
link (``/frames`` naming ``/frames`` of another file), a soft link (possibly to itself,
which HDF5 follows until it gives up), external storage (the dataset's bytes are any
file the user can read, ``/etc/...``) and a virtual dataset (assembled from datasets of
other files). holoview writes none of these, and a file that holds one would have
``process`` and ``peaks`` read, and ``record --source replay:`` copy, what lies outside
the recording. So every member a reader opens goes through :func:`open_member`: the
link's class is read first without following it (``H5Lget_info``), and only a hard link
is opened; a dataset must keep its bytes in the file (no external storage, not
virtual). Anything else is a one-line :class:`~holoview.errors.InputError` naming the
file and the member.

HDF5 has no file-access setting that refuses external links (``H5Pset_nlinks`` must
allow one; the external-link prefix only redirects relative names): never following a
link that is not a hard one is what keeps the reader in the file.
"""

from __future__ import annotations

from pathlib import Path
from typing import TypeVar

import h5py

from holoview.errors import InputError

__all__ = ["open_member"]

Member = TypeVar("Member", h5py.Dataset, h5py.Group)

_LINK_KINDS = {
    h5py.h5l.TYPE_SOFT: "a soft link",
    h5py.h5l.TYPE_EXTERNAL: "an external link",
}


def _refusal(path: Path, member: str, what: str) -> InputError:
    return InputError(
        f"{path}: {member} is {what}; holoview reads only data stored in the recording itself"
    )


def _link_target(group: h5py.Group, name: bytes, kind: int) -> str:
    """Where a soft or external link points, as text for a message."""
    try:
        value = group.id.links.get_val(name)
    except (KeyError, RuntimeError, OSError):
        return ""
    if kind == h5py.h5l.TYPE_EXTERNAL:
        filename, target = value
        return f" to {target.decode(errors='replace')} in {filename.decode(errors='replace')}"
    return f" to {value.decode(errors='replace')}" if isinstance(value, bytes) else ""


def open_member(group: h5py.Group, name: str, kind: type[Member], path: Path) -> Member | None:
    """Return the member ``name`` of ``group`` when it is a hard link to a ``kind``.

    Parameters
    ----------
    group : h5py.Group
        The group holding the member (itself opened by this function, or the root).
    name : str
        One name in ``group`` (no ``/``).
    kind : type
        ``h5py.Dataset`` or ``h5py.Group``.
    path : Path
        The recording, for messages.

    Returns
    -------
    h5py.Dataset or h5py.Group or None
        None when ``group`` has no member of that name.

    Raises
    ------
    InputError
        The member is a soft, external or user-defined link, of another kind than
        ``kind``, a dataset stored in other files (external storage) or assembled from
        them (virtual), or unreadable.
    """
    member = f"{group.name.rstrip('/')}/{name}"
    key = name.encode()
    try:
        if not group.id.links.exists(key):
            return None
        link = group.id.links.get_info(key).type
    except (KeyError, RuntimeError, OSError) as exc:
        raise _refusal(path, member, f"unreadable ({exc})") from exc
    if link != h5py.h5l.TYPE_HARD:
        what = _LINK_KINDS.get(link, f"a link of type {link}")
        raise _refusal(path, member, what + _link_target(group, key, link))
    try:
        found = group[name]
    except (KeyError, RuntimeError, OSError) as exc:
        raise _refusal(path, member, f"unreadable ({exc})") from exc
    if not isinstance(found, kind):
        wanted = "dataset" if kind is h5py.Dataset else "group"
        raise InputError(f"{path}: {member} is not a {wanted}")
    if isinstance(found, h5py.Dataset):
        if found.is_virtual:
            sources = sorted({source.file_name for source in found.virtual_sources()})
            raise _refusal(path, member, f"a virtual dataset of {', '.join(sources)}")
        if found.external:
            files = sorted({str(entry[0]) for entry in found.external})
            raise _refusal(path, member, f"stored in other files ({', '.join(files)})")
    return found
