"""Pick Mitsuba's variant once: ``llvm_ad_rgb`` when a usable libLLVM is present, else ``scalar_rgb``.

``llvm_ad_rgb`` needs a system libLLVM 19 (Debian's ``libllvm19``); LLVM 14 is refused and 15–16
abort on curve scenes. ``scalar_rgb`` needs nothing but is about 2x slower, and it cannot replace
curve geometry in memory. Set ``HAIRDIGI_VARIANT`` to force one.
"""
from __future__ import annotations

import os
import warnings

import mitsuba as mi

PREFERRED = ("llvm_ad_rgb", "scalar_rgb")


def select_variant(preferred: str | None = None) -> str:
    """Set and return the first variant that works, warning when it falls back to ``scalar_rgb``."""
    if mi.variant() is not None and preferred is None:
        return mi.variant()
    wanted = preferred or os.environ.get("HAIRDIGI_VARIANT")
    candidates = (wanted,) if wanted else PREFERRED
    errors = []
    for name in candidates:
        try:
            mi.set_variant(name)
            if name.startswith("llvm"):
                import drjit as dr
                dr.zeros(dr.llvm.Float, 1)  # raises when the LLVM backend is inactive
            break
        except Exception as exc:  # ImportError, or "LLVM backend is inactive"
            errors.append(f"{name}: {exc}")
    else:
        raise RuntimeError("no Mitsuba variant works: " + "; ".join(errors))
    if mi.variant() == "scalar_rgb" and not wanted:
        warnings.warn("llvm_ad_rgb is unavailable (install Debian's libllvm19); rendering with "
                      "scalar_rgb, about 2x slower. " + "; ".join(errors), RuntimeWarning, stacklevel=2)
    return mi.variant()


def is_jit() -> bool:
    return select_variant().startswith(("llvm", "cuda"))


select_variant()


def load_scene(scene_dict: dict):
    """``mi.load_dict`` with the scene's objects in the dict's order, so a seed gives one image.

    Mitsuba 3.9.1 orders a scene dict's shapes at random on each load (even with
    ``parallel=False``), and the order of the emitters decides which light a random number
    samples: two loads of one dict rendered different (equally valid) images. Objects that are
    instantiated one by one keep the order in which they are given.
    """
    children = {key: value if key == "type" or not isinstance(value, dict) else mi.load_dict(value)
                for key, value in scene_dict.items()}
    return mi.load_dict(children)
