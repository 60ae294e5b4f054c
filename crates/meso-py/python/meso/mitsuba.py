"""A Mitsuba 3 BSDF that evaluates and samples a meso material.

What it models
    The effective BRDF of a meso material (docs/material-format.md): an NDF convolved with a
    facet transfer function in the multiple-surface or the microfacet form of Fournier 1992,
    plus an optional Lambert term. Values come from :meth:`meso.Material.brdf`, directions from
    :meth:`meso.Material.sample` (a mixture of NDF-reflection and cosine sampling,
    ``meso_core::importance``) and densities from :meth:`meso.Material.pdf`. Reflection only,
    front side only: both directions must be above the shading normal, otherwise the value, the
    density and the sample weight are 0.

Parameters (plugin ``"meso"``; give exactly one of the two)
    ``material`` (string, no default)
        Path of a meso material TOML file, resolved by Mitsuba's file resolver (relative to the
        scene file when loaded from XML); relative paths inside it are resolved against the
        file's own directory.
    ``toml`` (string, no default)
        The material's TOML text inline; relative paths inside it are resolved against the
        current directory.

    Values are linear RGB, in 1/sr for the BRDF. The shading frame is Mitsuba's ``si.sh_frame``
    (normal +z, tangent ``s`` = +x), which meso's local frame (normal +z, tangent +x) is
    identified with. For an anisotropic material the tangent is therefore Mitsuba's (from the
    shape's ``dp_du``), which need not be the tangent of the same shape in a meso scene.

Frame mapping
    Mitsuba's ``si.wi`` points towards the viewer (the previous path vertex): it is meso's
    ``wo``. The BSDF's ``wo`` argument (and the sampled ``bs.wo``) points towards the light:
    it is meso's ``wi``. So ``eval(ctx, si, wo) = Material.brdf(wi=wo, wo=si.wi) · wo.z``.

Sampling contract (written once, here)
    ``sample`` returns ``(bs, weight)`` with ``bs.wo`` drawn with density ``bs.pdf`` (solid
    angle, 1/sr; equal to ``pdf(ctx, si, bs.wo)``) and ``weight = f · cos θ(bs.wo) / bs.pdf``,
    ``bs.eta = 1``, ``bs.sampled_type = GlossyReflection``, ``bs.sampled_component = 0``.
    A declined draw (meso returns density 0) or a direction below the surface gives
    ``weight = 0`` and ``pdf = 0``. ``sample1`` picks the strategy and ``sample2`` drives it
    (meso's ``u = (sample1, sample2.x, sample2.y)``).

Variants
    ``scalar_rgb``: one meso call per query. JIT variants (``llvm_ad_rgb``; ``cuda_*`` are
    untested): each query converts the whole wavefront to numpy (``np.array``), calls meso
    once on the batch (Rust, multi-threaded) and converts back. That needs evaluated arrays, so
    rendering a scene in a JIT variant requires ``dr.set_flag(dr.JitFlag.SymbolicLoops, False)``
    and ``dr.set_flag(dr.JitFlag.SymbolicCalls, False)`` (:func:`register` does this by
    default). No derivatives flow through the plugin (it is not differentiable). Monochrome or
    spectral variants are not supported (the values are RGB).

Usage
    >>> import mitsuba as mi
    >>> mi.set_variant("llvm_ad_rgb")     # or "scalar_rgb"
    >>> import meso.mitsuba
    >>> meso.mitsuba.register()
    >>> bsdf = mi.load_dict({"type": "meso", "material": "gold.toml"})

    or in a scene dict ``{"type": "sphere", "bsdf": {"type": "meso", "toml": "..."}}``.
    ``register()`` must be called once per variant (after ``mi.set_variant``).

References
    A. Fournier, "Normal distribution functions and multiple surfaces", Graphics Interface '92
    Workshop on Local Illumination, 1992 (the multiple-surface and microfacet forms).
    W. Jakob, S. Speierer, N. Roussel, D. Vicini et al., "Mitsuba 3 renderer", 2022,
    https://mitsuba-renderer.org (the BSDF interface and its sampling convention).
"""

from __future__ import annotations

import os
from typing import Dict

import numpy as np

import drjit as dr
import mitsuba as mi

from . import Material

__all__ = ["register", "MesoBSDF", "bsdf_class"]

_CLASSES: Dict[str, type] = {}


def _load_material(props) -> Material:
    has_file = "material" in props
    has_text = "toml" in props
    if has_file == has_text:
        raise ValueError('meso BSDF: give exactly one of "material" (a TOML file) or "toml" (text)')
    if has_file:
        path = str(props["material"])
        resolved = str(mi.file_resolver().resolve(path))
        if not os.path.exists(resolved):
            raise FileNotFoundError(f"meso BSDF: material file {path!r} not found")
        return Material.from_file(resolved)
    return Material.from_toml(str(props["toml"]))


def _width(*xs) -> int:
    return max(dr.width(x) for x in xs)


def _vec(x, n: int) -> np.ndarray:
    """A drjit 3-vector (scalar or JIT, width 1 or n) as an (n, 3) float64 array."""
    a = np.asarray(np.array(x), dtype=np.float64)
    if a.ndim == 1:
        a = a[:, None]
    return np.ascontiguousarray(np.broadcast_to(a, (3, n)).T)


def _flt(x, n: int) -> np.ndarray:
    a = np.asarray(np.array(x), dtype=np.float64).reshape(-1)
    return np.broadcast_to(a, (n,))


def _mask(active, n: int) -> np.ndarray:
    a = np.asarray(np.array(active), dtype=bool).reshape(-1)
    return np.broadcast_to(a, (n,))


def bsdf_class() -> type:
    """The BSDF class for the current Mitsuba variant (built once per variant)."""
    variant = mi.variant()
    if variant is None:
        raise RuntimeError("meso.mitsuba: call mi.set_variant(...) first")
    if variant in _CLASSES:
        return _CLASSES[variant]
    if "rgb" not in variant:
        raise RuntimeError(f"meso.mitsuba: variant {variant!r} is not supported (use an *_rgb one)")
    scalar = variant.startswith("scalar")

    # Conversions between meso's float64 (n, 3) / (n,) arrays and this variant's types.
    if scalar:

        def out_vec(a):  # (1, 3) -> Vector3f
            return mi.Vector3f(*(float(v) for v in a[0]))

        def out_col(a):
            return mi.Color3f(*(float(v) for v in a[0]))

        def out_flt(a):
            return mi.Float(float(a[0]))

    else:

        def out_vec(a):
            return mi.Vector3f(np.ascontiguousarray(a.T, dtype=np.float32))

        def out_col(a):
            return mi.Color3f(np.ascontiguousarray(a.T, dtype=np.float32))

        def out_flt(a):
            return mi.Float(np.ascontiguousarray(a, dtype=np.float32))

    flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide

    class MesoBSDF(mi.BSDF):
        """A meso material as a Mitsuba BSDF (see the module documentation)."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.material = _load_material(props)
            self.m_components = [flags]
            self.m_flags = flags

        # --- the meso calls, on numpy batches (meso's wi = light = Mitsuba's wo) ---
        # meso refuses zero or non-finite directions; rows with either direction at or below
        # the surface (or invalid, as inactive lanes may be) get a placeholder and a 0 result.
        def _valid(self, wi_light, wo_view):
            ok = (wi_light[:, 2] > 0.0) & (wo_view[:, 2] > 0.0)
            ok &= np.isfinite(wi_light).all(axis=1) & np.isfinite(wo_view).all(axis=1)
            up = np.array([0.0, 0.0, 1.0])
            return ok, np.where(ok[:, None], wi_light, up), np.where(ok[:, None], wo_view, up)

        def _f_cos(self, wi_light, wo_view):
            ok, li, vo = self._valid(wi_light, wo_view)
            if not ok.any():
                return np.zeros((len(ok), 3))
            f = self.material.brdf(li, vo)
            cos = li[:, 2] / np.linalg.norm(li, axis=1)
            return np.where(ok[:, None], f * cos[:, None], 0.0)

        def _pdf(self, wi_light, wo_view):
            ok, li, vo = self._valid(wi_light, wo_view)
            if not ok.any():
                return np.zeros(len(ok))
            return np.where(ok, self.material.pdf(vo, li), 0.0)

        def eval(self, ctx, si, wo, active=True):
            n = _width(si.wi, wo, active)
            if n == 0:
                return dr.zeros(mi.Color3f, 0)
            view, light = _vec(si.wi, n), _vec(wo, n)
            v = self._f_cos(light, view) * _mask(active, n)[:, None]
            return out_col(v)

        def pdf(self, ctx, si, wo, active=True):
            n = _width(si.wi, wo, active)
            if n == 0:
                return dr.zeros(mi.Float, 0)
            view, light = _vec(si.wi, n), _vec(wo, n)
            return out_flt(self._pdf(light, view) * _mask(active, n))

        def eval_pdf(self, ctx, si, wo, active=True):
            n = _width(si.wi, wo, active)
            if n == 0:
                return dr.zeros(mi.Color3f, 0), dr.zeros(mi.Float, 0)
            view, light = _vec(si.wi, n), _vec(wo, n)
            m = _mask(active, n)
            return out_col(self._f_cos(light, view) * m[:, None]), out_flt(self._pdf(light, view) * m)

        def sample(self, ctx, si, sample1, sample2, active=True):
            n = _width(si.wi, sample1, sample2, active)
            view = _vec(si.wi, n)
            u = np.empty((n, 3))
            u[:, 0] = _flt(sample1, n)
            s2 = np.asarray(np.array(sample2), dtype=np.float64)
            if s2.ndim == 1:
                s2 = s2[:, None]
            u[:, 1:] = np.broadcast_to(s2, (2, n)).T
            np.clip(u, 0.0, np.nextafter(1.0, 0.0), out=u)
            ok_view = (view[:, 2] > 0.0) & np.isfinite(view).all(axis=1)
            view_safe = np.where(ok_view[:, None], view, np.array([0.0, 0.0, 1.0]))
            light, pdf = self.material.sample(view_safe, u)
            ok = _mask(active, n) & ok_view & (pdf > 0.0) & (light[:, 2] > 0.0)
            pdf = np.where(ok, pdf, 0.0)
            light = np.where(ok[:, None], light, 0.0)
            fcos = self._f_cos(light, view)  # 0 where not ok (light.z = 0)
            weight = np.where(ok[:, None], fcos / np.where(ok, pdf, 1.0)[:, None], 0.0)

            bs = dr.zeros(mi.BSDFSample3f) if scalar else dr.zeros(mi.BSDFSample3f, n)
            bs.wo = out_vec(light)
            bs.pdf = out_flt(pdf)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(int(mi.BSDFFlags.GlossyReflection))
            bs.sampled_component = mi.UInt32(0)
            return bs, out_col(weight)

        def traverse(self, callback):
            pass

        def parameters_changed(self, keys):
            pass

        def to_string(self):
            return f"MesoBSDF[{self.material!r}]"

    MesoBSDF.__name__ = MesoBSDF.__qualname__ = "MesoBSDF"
    _CLASSES[variant] = MesoBSDF
    return MesoBSDF


def __getattr__(name):
    if name == "MesoBSDF":
        return bsdf_class()
    raise AttributeError(name)


def register(name: str = "meso", wavefront: bool = True) -> type:
    """Register the plugin ``name`` (default ``"meso"``) for the current variant; returns the class.

    In a JIT variant, ``wavefront=True`` (the default) also turns off Dr.Jit's symbolic loops and
    calls, which a Python BSDF calling numpy needs to render.
    """
    cls = bsdf_class()
    if wavefront and not mi.variant().startswith("scalar"):
        dr.set_flag(dr.JitFlag.SymbolicLoops, False)
        dr.set_flag(dr.JitFlag.SymbolicCalls, False)
    mi.register_bsdf(name, lambda props: cls(props))
    return cls
