"""meso — normal distribution functions and multiple surfaces (Fournier 1992) from Python.

The native core (``meso._meso``, Rust through PyO3) evaluates on numpy arrays with the GIL released:

* :class:`Material` — a meso material (docs/material-format.md): ``brdf(wi, wo)`` on ``(N, 3)``
  arrays of local-frame directions (``wi`` towards the light, ``wo`` towards the viewer, normal +z)
  gives ``(N, 3)`` RGB values in 1/sr, the same numbers as ``meso brdf``; ``sample`` / ``pdf`` are
  its importance sampler.
* :class:`Ndf` — an NDF normalised as Eq. 1, with ``eval``, ``sample`` and ``pdf``.
* :func:`read_heights` — a height-map image read as meso reads it (a numpy array of its codes);
  :func:`extract` / :func:`extract_file` — height maps filtered into NDF pyramids
  (:class:`Pyramid`, whose levels read as numpy arrays); :func:`render` — a scene file to a float
  image; :func:`export` — GGX roughness and normal mip chains, KTX2 and glTF.
* :mod:`meso.mitsuba` — a Mitsuba 3 BSDF plugin; :mod:`meso.batch` — batches on Dask.

Errors raise :class:`MesoError` (meso's message, naming the file and the problem),
``ValueError`` for bad arrays or parameters, ``TypeError`` for arguments that are not arrays of
numbers, and ``FileNotFoundError`` for missing inputs.
"""

from __future__ import annotations

from typing import Optional, Sequence

from ._meso import (  # noqa: F401  (re-exported)
    Level,
    Material,
    MesoError,
    Ndf,
    Pyramid,
    __version__,
    export,
    extract,
    extract_file,
    fit,
    fit_nonparametric,
    fit_samples,
    material_toml as _material_toml,
    read_heights,
    render,
    set_memory_budget,
)

__all__ = [
    "Level",
    "Material",
    "MesoError",
    "Ndf",
    "Pyramid",
    "__version__",
    "export",
    "extract",
    "extract_file",
    "fit",
    "fit_nonparametric",
    "fit_samples",
    "material_toml",
    "read_heights",
    "render",
    "set_memory_budget",
]


def material_toml(
    ndf: Optional[dict] = None,
    transfer: Optional[dict] = None,
    diffuse: Optional[Sequence[float]] = None,
    form: Optional[str] = None,
    shadowing: Optional[dict] = None,
    name: Optional[str] = None,
) -> str:
    """The material file text of the given tables (keys as in docs/material-format.md).

    ``ndf`` and ``transfer`` are dicts of the ``[ndf]`` and ``[transfer]`` tables
    (``{"kind": "beckmann", "alpha": 0.1}``), ``diffuse`` the Lambert albedo (RGB),
    ``form`` ``"multiple-surface"`` or ``"microfacet"``, ``shadowing`` the ``[shadowing]`` table.
    The tables are validated as a material file is (``transfer`` is required; ``MesoError``
    otherwise) and the text is written by meso's one material writer
    (``MaterialSpec::to_toml``): it reads back to the same material, with weights normalised
    as meso reads them.
    """
    return _material_toml(
        ndf=ndf, transfer=transfer, diffuse=diffuse, form=form, shadowing=shadowing, name=name
    )