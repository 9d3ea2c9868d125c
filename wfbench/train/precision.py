"""Mixed precision of the trainers' forward passes: the autocast dtype of a run and its context.

``docs/performance.md`` says what bf16 autocast buys on CUDA; the CPU tests run the same
dtype path (``tests/train/test_amp.py``).
"""

from __future__ import annotations

import torch

AMP_DTYPES = {"bfloat16": torch.bfloat16, "float16": torch.float16}


def amp_dtype(device: torch.device, bf16: bool, amp: str | torch.dtype | None = "auto") -> torch.dtype | None:
    """The autocast dtype of a run's forward passes; None: float32 (no autocast).

    ``amp="auto"`` (what ``wfbench train`` uses): bfloat16 on CUDA when ``bf16``, float32
    on CPU. Otherwise ``amp`` is the dtype itself (``torch.bfloat16``, ``torch.float16``
    or their names) on whatever device the run is, CPU included, or None for float32:
    the CPU tests run the trainers' CUDA dtype path this way (``torch.autocast("cpu", ...)``,
    tests/train/test_amp.py).
    """
    if isinstance(amp, str):
        if amp == "auto":
            return torch.bfloat16 if device.type == "cuda" and bf16 else None
        if amp not in AMP_DTYPES:
            raise ValueError(f"amp {amp!r} is not allowed; allowed: auto, {', '.join(AMP_DTYPES)}")
        return AMP_DTYPES[amp]
    if amp is not None and amp not in AMP_DTYPES.values():
        raise ValueError(f"amp {amp!r} is not allowed; allowed: auto, None, {', '.join(AMP_DTYPES)}")
    return amp


def autocast(device: torch.device, amp: torch.dtype | bool | None):
    """Autocast of a forward pass in dtype ``amp`` on ``device``'s type; None: a no-op context (float32).

    ``amp`` is a run's :func:`amp_dtype` (``Run.amp``); a bool is the older ``bf16`` flag
    (bfloat16 on CUDA only). The network keeps its heads in float32 either way.
    """
    if isinstance(amp, bool):
        amp = amp_dtype(device, amp)
    return torch.autocast(device_type=device.type, dtype=amp or torch.bfloat16, enabled=amp is not None)
