"""Pick Mitsuba's variant once: ``llvm_ad_rgb`` when a usable libLLVM is present, else ``scalar_rgb``.

``llvm_ad_rgb`` needs a system libLLVM 19 (Debian's ``libllvm19``); LLVM 14 is refused and 15–16
abort on curve scenes. ``scalar_rgb`` needs nothing but is about 2x slower, and it cannot replace
curve geometry in memory. Set ``HAIRDIGI_VARIANT`` to force one.

``select_variant("auto")`` (the command line's ``--variant auto``) tries ``cuda_ad_rgb`` first, with
a one-float allocation on the GPU to prove that Mitsuba finds one. A variant can be switched only
while no Mitsuba object exists: the command line switches before it loads any scene.

Importing this module chooses nothing: the entry points (the command line, the app) choose, or else
the first renderer or scene builder that needs Mitsuba objects calls ``select_variant()``.
"""
from __future__ import annotations

import os
import warnings

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.interrupt import sigint_held, stop_among
from hairdigi.render.domain.threads import plan

with sigint_held():   # threads started while Mitsuba loads inherit the block (render.domain.interrupt)
    import drjit as dr
    import mitsuba as mi

from hairdigi.render.domain.bounds import AUTO_VARIANTS as AUTO  # noqa: E402  (tried by "auto", in order)
from hairdigi.render.domain.bounds import PREFERRED_VARIANTS as PREFERRED  # noqa: E402


class VariantError(HairdigiError, RuntimeError):
    """No asked-for Mitsuba variant works on this machine (a one-line message saying why)."""


def _why_not(name: str, exc: Exception) -> str:
    """Why a variant cannot run, in words (Dr.Jit's own messages name its internals: ``jit_init(...)``)."""
    if name.startswith("cuda"):
        return "no usable NVIDIA GPU here (no CUDA device or driver)"
    text = " ".join(str(exc).split())
    plain = [s for s in text.split(". ") if "jit_" not in s and "JitBackend" not in s]
    return ". ".join(plain) or "its backend does not start (for llvm variants: install Debian's libllvm19)"


def select_variant(preferred: str | None = None) -> str:
    """Set and return the first variant that works, warning when it falls back to ``scalar_rgb``.

    ``preferred`` None keeps the variant already set; ``"auto"`` tries ``AUTO`` (or
    ``HAIRDIGI_VARIANT`` when set); a variant name sets exactly that one or raises VariantError.
    """
    if mi.variant() is not None and (preferred is None or preferred == mi.variant()):
        return mi.variant()
    env = os.environ.get("HAIRDIGI_VARIANT")
    wanted = env if preferred in (None, "auto") else preferred
    candidates = (wanted,) if wanted else AUTO if preferred == "auto" else PREFERRED
    errors = []
    for name in candidates:
        try:
            with sigint_held():   # the backend's pool starts here: its threads never take Ctrl-C
                mi.set_variant(name)
                if name.startswith(("llvm", "cuda")):
                    # raises when the backend is inactive (no libLLVM; no GPU or CUDA driver)
                    dr.zeros((dr.cuda if name.startswith("cuda") else dr.llvm).Float, 1)
            break
        except Exception as exc:  # ImportError, or "LLVM backend is inactive"
            stop = stop_among(exc)
            if stop is not None:   # a SIGTERM or Ctrl-C during the import, wrapped as an import error
                raise stop from None
            errors.append(f"{name}: {_why_not(name, exc)}")
    else:
        raise VariantError("no Mitsuba variant works: " + "; ".join(errors)
                           + ("; use --variant auto" if preferred not in (None, "auto") else ""))
    if mi.variant().startswith(("llvm", "cuda")):   # the path tracer's pool: the process's thread budget
        with sigint_held():
            dr.set_thread_count(plan()["drjit"])
    if mi.variant() == "scalar_rgb" and not wanted:
        warnings.warn("llvm_ad_rgb is unavailable (install Debian's libllvm19); rendering with "
                      "scalar_rgb, about 2x slower. " + "; ".join(errors), RuntimeWarning, stacklevel=2)
    return mi.variant()


def spectral_variant() -> str:
    """The spectral twin of the variant set (``llvm_ad_rgb`` -> ``llvm_ad_spectral``): spectral scenes
    load and render inside ``mi.variant_context(spectral_variant())``, beside the RGB ones."""
    name = select_variant()
    twin = name.replace("_rgb", "_spectral")
    if twin not in mi.variants():
        raise VariantError(f"Mitsuba has no spectral twin of {name} ({twin}); install the mitsuba wheel from PyPI")
    return twin


def is_jit() -> bool:
    return select_variant().startswith(("llvm", "cuda"))


def transform(matrix) -> "mi.ScalarTransform4f":
    """A 4 x 4 matrix (numpy or nested lists) as a Mitsuba scalar transform, for scene dicts."""
    select_variant()
    return mi.ScalarTransform4f([[float(v) for v in row] for row in matrix])


def load_scene(scene_dict: dict):
    """``mi.load_dict`` with the scene's objects in the dict's order, so a seed gives one image.

    Mitsuba 3.9.1 orders a scene dict's shapes at random on each load (even with
    ``parallel=False``), and the order of the emitters decides which light a random number
    samples: two loads of one dict rendered different (equally valid) images. Objects that are
    instantiated one by one keep the order in which they are given.
    """
    select_variant()
    children = {key: value if key == "type" or not isinstance(value, dict) else mi.load_dict(value)
                for key, value in scene_dict.items()}
    return mi.load_dict(children)
