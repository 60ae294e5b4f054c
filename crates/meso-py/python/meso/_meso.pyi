"""Type stubs of the native module ``meso._meso`` (Rust, PyO3). Directions are unit vectors in the
local frame (normal +z, tangent +x); ``wi`` points towards the light, ``wo`` towards the viewer;
BRDF values are RGB in 1/sr without the cosine."""

from os import PathLike
from typing import Any, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, PathLike[str]]
_Array = npt.ArrayLike

__version__: str

class MesoError(Exception):
    """An error reported by meso: the message names the file, the field and the problem."""

class Material:
    """A meso material (docs/material-format.md)."""

    @staticmethod
    def from_toml(text: str, base_dir: Optional[_Path] = None) -> Material: ...
    @staticmethod
    def from_file(path: _Path) -> Material: ...
    @staticmethod
    def from_params(base_dir: Optional[_Path] = None, **tables: Any) -> Material: ...
    @property
    def name(self) -> Optional[str]: ...
    @property
    def toml(self) -> str: ...
    @property
    def form(self) -> str: ...
    @property
    def ndf(self) -> Ndf: ...
    def brdf(self, wi: _Array, wo: _Array, exact: bool = False) -> npt.NDArray[np.float64]:
        """(N, 3) RGB BRDF values in 1/sr at (N, 3) direction pairs; the numbers of ``meso brdf``
        (its compiled plan; ``exact=True``: the quadrature of every pair, ``meso brdf --exact``)."""
    def sample(self, wo: _Array, u: _Array) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Directions towards the light (N, 3) and their densities (N,) in 1/sr, for viewer
        directions ``wo`` (N, 3) and uniform numbers ``u`` (N, 3); declined draws have pdf 0."""
    def pdf(self, wo: _Array, wi: _Array) -> npt.NDArray[np.float64]:
        """(N,) density in 1/sr with which ``sample`` draws ``wi`` given ``wo``."""

class Ndf:
    """A normal distribution function, ∫ n(m) dω = 1 over the sphere (Eq. 1)."""

    @staticmethod
    def from_toml(text: str, base_dir: Optional[_Path] = None) -> Ndf: ...
    @staticmethod
    def from_params(base_dir: Optional[_Path] = None, **keys: Any) -> Ndf: ...
    @property
    def kind(self) -> str: ...
    @property
    def singular(self) -> bool: ...
    def eval(self, m: _Array) -> npt.NDArray[np.float64]:
        """(N,) density n(m) in 1/sr at (N, 3) unit normals."""
    def sample(self, u: _Array) -> npt.NDArray[np.float64]:
        """(N, 3) normals drawn with (N, 2) uniform numbers; density ``pdf``."""
    def pdf(self, m: _Array) -> npt.NDArray[np.float64]: ...
    def stats(self) -> dict[str, Any]:
        """``{"integral": ∫ n dω, "mean_normal": [x, y, z]}`` by quadrature."""

class Level:
    """One pyramid level: rows × cols texels of up to K Phong lobes (Eq. 12), zero-padded."""

    @property
    def rows(self) -> int: ...
    @property
    def cols(self) -> int: ...
    @property
    def span(self) -> int: ...
    @property
    def counts(self) -> npt.NDArray[np.int64]:
        """(rows, cols) lobes per texel."""
    @property
    def axes(self) -> npt.NDArray[np.float64]:
        """(rows, cols, K, 3) unit lobe axes."""
    @property
    def weights(self) -> npt.NDArray[np.float64]:
        """(rows, cols, K) lobe weights, each texel's summing to 1."""
    @property
    def exponents(self) -> npt.NDArray[np.float64]:
        """(rows, cols, K) Phong exponents η of cos^η(α/2)."""
    @property
    def residual(self) -> float:
        """Mean relative NDF L2 residual of the level's measured texels: the lobes' NDF against
        the histogram of the texel's normals on equal-area bins of about 6°. It reads 1 or more
        where a relief's normals lie within a few degrees of +z (four bins meet there) however
        good the fit; ``shading_error`` is the measure of how the lobes shade."""
    @property
    def residual_max(self) -> float:
        """Largest NDF residual among the level's measured texels."""
    @property
    def shading_error(self) -> Optional[float]:
        """Mean shading error, a fraction of each texel's peak (0.01 = 1 %); None if not recorded."""
    @property
    def shading_error_max(self) -> Optional[float]:
        """Largest shading error (fraction of the peak); None if not recorded."""
    @property
    def lobe_shares(self) -> npt.NDArray[np.float64]:
        """(rows, cols, K) each lobe's share of its texel's projected area (summing to 1)."""
    def lobe_visibility(
        self, direction: Sequence[float], view: Optional[Sequence[float]] = None
    ) -> Optional[npt.NDArray[np.float64]]:
        """(rows, cols, K) per lobe, the fraction of the cells it stands for from which
        ``direction`` (normalised; +z the normal, +y up in the image) is above the horizon (none
        below it), or with ``view`` (normalised) from which both are (shadowing and masking together); on level 0 each
        lobe reads its cell's horizons point by point, as the renderer does; None for a
        pyramid from a normal map."""

class Pyramid:
    """An NDF pyramid (docs/map-format.md); level 0 finest, ``top`` one texel."""

    @staticmethod
    def read(path: _Path) -> Pyramid: ...
    def write(self, path: _Path) -> None: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def texel_size(self) -> float: ...
    @property
    def max_lobes(self) -> int: ...
    @property
    def levels(self) -> list[Level]: ...
    @property
    def top(self) -> Level: ...
    def __len__(self) -> int: ...

def extract(
    heights: _Array,
    texel_size: float,
    height_scale: float = 1.0,
    max_lobes: Optional[int] = None,
    border: str = "wrap",
    normals: str = "triangles",
    method: str = "lobes",
    merge_levels: str = "plain",
) -> Pyramid:
    """The NDF pyramid of a (rows, cols) height array (heights × height_scale, length units;
    row 0 at the top of the image). texel_size and height_scale must lie in [1e-12, 1e12] and
    height_scale / texel_size be at most 1e6, as for `meso extract` (else ValueError).
    max_lobes: lobes per texel at most, on every map; None: 4, or 6 on a map of faces and walls
    (a tenth of its projected area within 10° of the normal and a tenth more than 45° from it),
    as `meso extract`."""

def read_heights(path: _Path, border: str = "wrap") -> tuple[npt.NDArray[np.float64], list[str]]:
    """A height-map image read as ``meso extract`` reads it (budget, checks, 8-bit
    dequantisation): ``(heights, warnings)``, a (rows, cols) array in image order (row 0 the top)
    of the codes in [0, 1] (an EXR's values as they are); ``extract(heights, S, height_scale=H)``
    is ``meso extract`` of the image with ``--texel-size S --height-scale H``."""

def extract_file(
    path: _Path,
    out: _Path,
    texel_size: Optional[float] = None,
    height_scale: Optional[float] = None,
    max_lobes: Optional[int] = None,
    normal_map: bool = False,
    convention: str = "gl",
    border: str = "wrap",
    normals: str = "triangles",
    method: str = "lobes",
    merge_levels: str = "plain",
) -> tuple[Pyramid, list[str]]:
    """``meso extract PATH --out OUT``: the same map file, and the CLI's warnings."""

def render(
    scene: _Path,
    spp: Optional[int] = None,
    width: Optional[int] = None,
    height: Optional[int] = None,
    seed: int = 0,
) -> npt.NDArray[np.float32]:
    """``meso render``: (height, width, 3) linear radiance, W/(m²·sr)."""

def export(
    path: _Path,
    out: _Path,
    texel_size: Optional[float] = None,
    height_scale: Optional[float] = None,
    convention: Optional[str] = None,
    alpha: Optional[float] = None,
    roughness_map: Optional[_Path] = None,
    metallic: Optional[float] = None,
    base_color: Optional[_Path] = None,
    anisotropic: bool = False,
    lobes: Optional[_Path] = None,
) -> tuple[list[str], list[dict[str, Any]], list[str]]:
    """``meso export PATH --out OUT``: written files, per-level statistics, warnings. ``path``: a
    normal map, a height map (with ``texel_size`` and ``height_scale``) or a material file
    (``.toml``, no other option). ``convention`` defaults to ``"gl"``, ``alpha`` to 0.1,
    ``metallic`` to 0 (None: the default; a material file refuses any given option);
    ``anisotropic``: KHR_materials_anisotropy lobes (``--anisotropic``); ``lobes``: a lobe
    pyramid's map file (``--lobes``)."""

def set_memory_budget(size: Union[int, float, str]) -> None:
    """The memory budget (bytes or "8G"); larger work raises MesoError before it starts. A size
    that is not one (0, negative, an unknown suffix) raises ValueError with the CLI's message."""

def fit(
    data: _Path,
    lobes: Union[int, str] = "auto",
    transfer: str = "auto",
    metric: str = "both",
    axes: str = "auto",
    out: Optional[_Path] = None,
    samples: int = 30000,
) -> tuple[Material, dict[str, Any]]:
    """``meso fit DATA --lobes K``: the fitted material and a report (description, lobes, model,
    ``transfer`` kept of ``"phong"``, ``"microfacet"``, ``"ggx-lobes"`` (``"auto"`` tries all three),
    or ``"student-t-lobes"`` when asked for (GGX, Beckmann or Student-t lobes, γ fitted; not in auto),
    ``fitted``/``held_out`` errors per channel: ``ngan_l2`` in 1/sr and ``low_log``, the TOML);
    ``out`` also writes the material file."""

def fit_nonparametric(
    data: _Path,
    out: Optional[_Path] = None,
    samples: int = 30000,
    grid: Optional[tuple[int, int]] = None,
) -> tuple[Material, dict[str, Any]]:
    """``meso fit DATA --nonparametric [--grid N_Z,N_PHI]``: from a MERL table, the NDF tabulated
    in θm from its back-scattering cells (``kind`` ``"radial"``; report ``nodes``,
    ``rms_theta_deg``, ``start``; ``grid`` must be None); from a sample CSV, the NDF tabulated
    over an equal-area grid of ``grid = (n_z, n_phi)`` cells (default 512 × 64, ``n_z`` even) from
    its back-scattering samples (``kind`` ``"tabulated"``; report ``grid``, ``back_samples``,
    ``cells_covered``, ``cells_needed``). Both: Smith derived from the NDF, Schlick ``f0``,
    ``specular`` and ``albedo`` fitted, ``engine`` (glTF metallic-roughness of the best single
    GGX + Lambert, as ``fit``'s), ``fitted``/``held_out`` errors per channel, the TOML;
    ``out`` also writes the file."""

def fit_samples(
    wi: _Array,
    wo: _Array,
    values: _Array,
    lobes: Union[int, str] = "auto",
    transfer: str = "auto",
    metric: str = "both",
    axes: str = "auto",
    out: Optional[_Path] = None,
) -> tuple[Material, dict[str, Any]]:
    """``fit`` on (N, 3) arrays: ``wi`` towards the light, ``wo`` towards the viewer (local frame),
    ``values`` RGB BRDF in 1/sr."""

def material_toml(
    ndf: Optional[dict[str, Any]] = None,
    transfer: Optional[dict[str, Any]] = None,
    diffuse: Optional[Any] = None,
    form: Optional[str] = None,
    shadowing: Optional[dict[str, Any]] = None,
    name: Optional[str] = None,
) -> str:
    """A material file from its tables, validated and written by ``MaterialSpec::to_toml``."""
