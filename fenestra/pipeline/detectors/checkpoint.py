"""Loading a detector checkpoint and choosing its device, with one-line errors.

    ckpt = read_checkpoint(path, "winnet")   # FenestraError if missing, not a model, or another arch
    check_device("cuda")                     # FenestraError if no CUDA GPU is visible
"""
from __future__ import annotations

from pathlib import Path

from fenestra.errors import FenestraError


def check_device(device: str) -> str:
    """``device`` if torch can use it here: "cpu", or "cuda[:n]" with a visible GPU n."""
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    if device == "cpu":
        return device
    if not str(device).startswith("cuda"):
        raise FenestraError(f"unknown device {device!r}; use cpu or cuda")
    n = torch.cuda.device_count() if torch.cuda.is_available() else 0
    index = int(device.split(":")[1]) if ":" in device and device.split(":")[1].isdigit() else 0
    if index >= n:
        raise FenestraError(f"--device {device}: {'no CUDA GPU is available' if n == 0 else f'only {n} CUDA GPU(s)'} "
                            "on this machine; use --device cpu")
    return device


def read_checkpoint(path: Path, arch: str | tuple[str, ...]) -> dict:
    """The checkpoint dict at ``path`` (torch.load on the CPU) holding an ``arch`` model (or one of
    several architectures).

    Read with torch's restricted unpickler (``weights_only=True``: tensors, containers, numbers,
    strings; plus torch's version string, which training's ``meta`` holds): a file that would run
    code when unpickled is refused, not executed. FenestraError naming the file if it is not a
    torch checkpoint of that architecture.
    """
    import torch  # noqa: PLC0415 (torch: imported when first used, not at the package's import)
    from torch.torch_version import TorchVersion  # noqa: PLC0415 (torch: imported when first used, not at the package's import)

    try:
        with torch.serialization.safe_globals([TorchVersion]):
            ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001 - pickle, zip and torch errors all mean "not a model"
        raise FenestraError(f"{path} is not a model checkpoint ({type(e).__name__}: "
                            f"{' '.join(str(e).split())[:120]})") from e
    archs = (arch,) if isinstance(arch, str) else tuple(arch)
    if not isinstance(ckpt, dict) or ckpt.get("arch") not in archs:
        got = ckpt.get("arch") if isinstance(ckpt, dict) else type(ckpt).__name__
        raise FenestraError(f"{path} holds a {got!r} model, not {' or '.join(map(repr, archs))}")
    return ckpt
