"""What the `run` and `fit` commands share: the bad-input error and the output folder
check."""

from pathlib import Path


class InputError(Exception):
    """Bad command-line input: reported with exit status 2."""


def prepare_out(out: Path, names, overwrite: bool) -> Path:
    """Create the output folder and check that `names` can be written in it.

    Run before the solve, so that a bad `--out` costs nothing: an `--out` that is a
    file, lies under a file, or cannot be created or written raises `InputError`
    (exit status 2) naming the path; so do existing outputs unless `overwrite`.
    """
    import os
    import tempfile

    if out.exists() and not out.is_dir():
        raise InputError(f"--out {str(out)!r} exists and is not a directory")
    parent = out
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise InputError(
            f"--out {str(out)!r}: {str(parent)!r} is a file, not a directory"
        )
    try:
        out.mkdir(parents=True, exist_ok=True)
        # os.access is no proof (root, read-only mounts): write a probe file.
        fd, probe = tempfile.mkstemp(prefix=".jaxcontact-probe-", dir=out)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise InputError(
            f"--out {str(out)!r} is not a writable directory "
            f"({exc.strerror or exc})"
        ) from None
    for name in names:
        if (out / name).resolve().parent != out.resolve():
            raise InputError(f"output {name!r} would be written outside --out {out}")
    clash = [name for name in names if (out / name).exists()]
    folders = [name for name in clash if (out / name).is_dir()]
    if folders:
        raise InputError(
            f"--out {str(out)!r}: {', '.join(folders)} is a directory, not an output "
            "file"
        )
    if clash and not overwrite:
        raise InputError(
            f"--out {str(out)!r} already holds {', '.join(clash)}: pass --overwrite to "
            "replace them, or choose another --out"
        )
    return out
