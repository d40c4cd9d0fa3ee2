"""Which arithmetic the network runs in: fp32, or bf16 where the hardware multiplies it natively.

One rule for training and for sampling. On the CPU, bf16 only where oneDNN runs bf16
convolutions natively (AVX-512 BF16 or AMX): there a tiny-preset training step is about 1.2×
faster and trains as well, and sampling is about 1.5× faster with the same metrics
(docs/benchmarks.md, "bf16 on the CPU"); ``auto`` takes it there and fp32 elsewhere; fp16, and
bf16 asked of a CPU without it, are refused. Weights, optimiser state and the sampler's own
arithmetic stay fp32: only the network's matrix products and convolutions run under autocast.
"""

from __future__ import annotations

import torch

CHOICES = ("auto", "no", "fp16", "bf16")


def cpu_has_native_bf16() -> bool:
    """True where oneDNN runs bf16 convolutions natively on this CPU (AVX-512 BF16 or AMX)."""
    try:
        return bool(torch.backends.mkldnn.is_available() and torch.ops.mkldnn._is_mkldnn_bf16_supported())
    except (AttributeError, RuntimeError):
        return False


def training_precision(choice: str, device: str | None) -> str:
    """accelerate's mixed_precision ("no", "bf16" or "fp16") for a ``--mixed-precision`` choice."""
    if choice not in CHOICES:
        raise ValueError(f"mixed_precision must be auto, no, fp16 or bf16, got {choice!r}")
    if device == "cpu" or not torch.cuda.is_available():
        native = choice in ("auto", "bf16") and cpu_has_native_bf16()
        if choice in ("auto", "no") or native:
            return "bf16" if native else "no"
        raise ValueError(
            f"mixed_precision {choice}: this CPU has no native {choice} arithmetic "
            "(bf16 needs AVX-512 BF16 or AMX); use auto or no"
        )
    if choice == "auto":
        return "bf16" if torch.cuda.is_bf16_supported() else "fp16"
    return choice


def sampling_dtype(choice: str, device: torch.device) -> torch.dtype | None:
    """The autocast dtype sampling runs the network in (None: fp32) for a ``--mixed-precision`` choice.
    On the CPU the training rule; on a GPU fp32 unless bf16 or fp16 is asked for (``auto`` was not
    measured there)."""
    if device.type == "cpu":
        return torch.bfloat16 if training_precision(choice, "cpu") == "bf16" else None
    if choice not in CHOICES:
        raise ValueError(f"mixed_precision must be auto, no, fp16 or bf16, got {choice!r}")
    return autocast_dtype(choice) if choice != "auto" else None


def autocast_dtype(mixed_precision: str) -> torch.dtype | None:
    """The autocast dtype of accelerate's ``mixed_precision`` ("no", "bf16", "fp16"; None: fp32): what a
    model trained that way samples its validation frames in."""
    dtypes = {"no": None, "bf16": torch.bfloat16, "fp16": torch.float16}
    if mixed_precision not in dtypes:
        raise ValueError(f"mixed_precision must be no, bf16 or fp16, got {mixed_precision!r}")
    return dtypes[mixed_precision]


def arithmetic_words(dtype: torch.dtype | None) -> str:
    """How a report names the arithmetic: "fp32" or "bf16 autocast"."""
    return "fp32" if dtype is None else f"{str(dtype).removeprefix('torch.').replace('bfloat16', 'bf16')} autocast"
