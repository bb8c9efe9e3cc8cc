"""Where training's commands write their files: every weights file, training state and loss log
under fenestra.outputs' rule (``fenestra train --out``, ``ship-weights --to``, ``train-verifier
--out``, ``train-refine --out``).

    check(path, inputs, force, own=WEIGHTS_FILE)  # before the training: refuse a bad --out
    save(path, ckpt, inputs, force)                # torch.save atomically, listed in its folder's manifest

A file is replaced only when its folder's manifest lists it with its digest (Fenestra wrote it),
or with ``force`` when it is recognised as this writer's kind of file (:data:`WEIGHTS_FILE`,
:data:`TRAINING_STATE`, :data:`LOSS_LOG`: an older Fenestra's output, or the shipped weights of
a checkout whose manifest is missing); never one of the command's inputs (the weights it starts
from or ships, its datasets) nor a file inside an input folder.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path

from fenestra import outputs

MAX_RECOGNISED_BYTES = 1 << 31  # a larger file is never loaded to be recognised


def torch_dict_with(keys: Iterable[str]) -> Callable[[Path], bool]:
    """An outputs.Recognised test: a torch checkpoint (read with torch's restricted unpickler:
    nothing runs) holding a dict with every one of ``keys``."""
    want = frozenset(keys)

    def test(path: Path) -> bool:
        import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)
        from torch.torch_version import TorchVersion  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

        try:
            if path.stat().st_size > MAX_RECOGNISED_BYTES:
                return False
            with torch.serialization.safe_globals([TorchVersion]):
                doc = torch.load(path, map_location="cpu", weights_only=True)
        except Exception:  # noqa: BLE001 - not a torch file, or one that needs code to load: not ours
            return False
        return isinstance(doc, dict) and want <= doc.keys()
    return test


def _loss_log(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            return f.read(32).startswith(b"iteration,elapsed_s,lr")
    except OSError:
        return False


WEIGHTS_FILE = outputs.Recognised("a weights file", torch_dict_with(("arch",)))
TRAINING_STATE = outputs.Recognised("a training state", torch_dict_with(("model", "opt", "iteration")))
LOSS_LOG = outputs.Recognised("a training loss log", _loss_log)


def check(path: str | Path, inputs: Iterable[str | Path | None] = (), force: bool = False, option: str = "--out",
          own: outputs.Recognised = WEIGHTS_FILE) -> None:
    """OwnershipError (one line, naming ``path``) when ``path`` may not receive this kind of file
    (fenestra.outputs.check_file; ``inputs``: files and folders the command reads)."""
    outputs.check_file(Path(path), inputs=inputs, option=option, force=force, own=own)


def save(path: str | Path, obj: object, inputs: Iterable[str | Path | None] = (), force: bool = False,
         option: str = "--out", own: outputs.Recognised = WEIGHTS_FILE) -> Path:
    """``torch.save(obj)`` to ``path`` atomically (a kill leaves the previous file or none), listed
    with its digest in its folder's manifest; the rule of :func:`check`."""
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    return outputs.write_file(Path(path), lambda p: torch.save(obj, p), inputs=inputs, option=option, force=force,
                              own=own)


def copy(path: str | Path, data: bytes, inputs: Iterable[str | Path | None] = (), force: bool = False,
         option: str = "--to") -> Path:
    """A weights file's bytes written to ``path`` under the rule of :func:`check` (shipping)."""
    return outputs.write_file(Path(path), lambda p: p.write_bytes(data) == len(data), inputs=inputs, option=option,
                              force=force, own=WEIGHTS_FILE)
