//! [`NdfMapped`]: the NDF-mapped material, shaded from the pyramid's filtered lobes (module docs
//! of [`crate::mapped`]).
//!
//! This module holds the material (its per-level tables, options and the [`Shader`] entry
//! points, which blend the taps' per-texel responses); the sub-modules hold its parts:
//!
//! * `build` — [`NdfMapped::new`] (every level's table up front, one tile a level) and
//!   [`NdfMapped::from_pyramid`] (tiles of 64² texels built when first read, under a byte cap,
//!   [`NdfMapped::with_table_cap`]): the tables from a pyramid, with each lobe's share of its
//!   texel's projected area and its horizon statistics from [`meso_maps::lobe_stats_by_cell`]
//!   or, per tile, [`meso_maps::rect_lobe_stats_by_cell`] (handed down from the level-0
//!   normals; level 0's once per texel);
//! * `lobes` — a texel's lobes as spherical Gaussians and their closed-form response under
//!   Phong facets and, through a core of Blinn–Phong peaks, isotropic microfacet facets, and
//!   the 7-node form of a lobe for other facets (and for microfacets' sharp lobes and the rest
//!   beside the core);
//! * `filter` — the level of detail and the filter taps (trilinear, box, sharp
//!   magnification);
//! * `memo` — the texels' responses a thread keeps from one shading call to the next when
//!   they ask the same directions (an orthographic camera and directional lights on a flat
//!   surface: a far view reads each texel for every pixel whose footprint holds it), the
//!   image the same bit for bit;
//! * `peak_quadrature` (tests only) — the brute-force quadrature over one Phong peak that the
//!   tests of `lobes` check against.
//!
//! # Conventions
//! * Texels are indexed row-major per level (`row · cols + col`), wrapped periodically;
//!   positions are in level-0 cells (`uv · texels_per_uv`).
//! * Within a tile's tables, a texel's lobes are `lobes[lobe_start[t]..lobe_start[t + 1]]`,
//!   its nodes (Lambert and general facets) `nodes[node_start[t]..node_start[t + 1]]`, `t` its
//!   row-major index in the tile.

use super::*;

mod build;
mod filter;
mod lobes;
mod memo;
#[cfg(test)]
mod peak_quadrature;
mod view;

use build::Source;
use filter::Tap;
pub use filter::{
    default_box_detail, BROAD_BOX_DETAIL, DEFAULT_MAX_BOX_DETAIL, GLOSSY_BOX_DETAIL_FROM,
    MAX_BOX_DETAIL,
};
pub(super) use lobes::MicrofacetCore;
use lobes::{microfacet_texel, phong_texel, Node, SgLobe, Shape, NO_LOBE};
pub use memo::MEMO_BYTES;
use memo::{TexelMemo, HEAD, PER_LIGHT};
use meso_maps::{
    frechet_dependence, with_frechet_dependence, CellHorizon, HorizonCdf, HorizonDirection,
    HorizonJoint, HorizonPair, HorizonStats, HorizonToward, Horizons, TowardReading,
};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use view::{TexelView, ViewLobe, SEEN_FADE, SEEN_FLOOR};

/// The tables of one tile of a level of the filtered pyramid (a rectangle of its texels; a
/// whole level when built eagerly, [`NdfMapped::new`]): texels are indexed row-major within
/// the tile, and lobe sources (`src`) among the tile's pyramid lobes, in texel order.
#[derive(Clone, Debug, PartialEq)]
struct NodeLevel {
    /// Texels along x of the tile.
    cols: usize,
    /// Texels along y of the tile.
    rows: usize,
    /// Level-0 cells a texel of the level spans.
    span: f64,
    /// Per texel, its lobes `lobes[lobe_start[t]..lobe_start[t + 1]]`.
    lobe_start: Vec<u32>,
    lobes: Vec<SgLobe>,
    /// The shapes the lobes index (one per distinct exponent of the tile).
    shapes: Vec<Shape>,
    /// Nodes for a general facet transfer (empty otherwise).
    node_start: Vec<u32>,
    nodes: Vec<Node>,
    /// Per texel, its horizon statistics (with shadowing), in the pyramid level's precision
    /// (`f32` on its big levels, read back as the same `f64` values: `Horizons::get`).
    horizon: Option<Horizons>,
    /// Per pyramid lobe of the tile (the `src` of [`SgLobe`] and [`Node`]), the horizon
    /// distribution of the cells it stands for (with shadowing, above level 0).
    lobe_horizon: Option<Vec<HorizonCdf>>,
    /// On level 0 (with shadowing), per texel its cell's horizons kept point by point, which
    /// all the texel's lobes stand for (`meso_maps::LobeStats::cells`): the light and the
    /// viewer read together per sub-cell.
    cells: Option<Vec<CellHorizon>>,
    /// Per pyramid lobe of the tile, from level [`meso_maps::JOINT_FROM_LEVEL`] on (with
    /// shadowing), the joint horizon distribution of the cells it stands for: how it sees a
    /// light and a viewer far apart in azimuth together.
    lobe_joint: Option<Vec<HorizonJoint>>,
    /// Per pyramid lobe of the tile, from level [`meso_maps::JOINT_FROM_LEVEL`] on (with
    /// shadowing), the horizon distributions of its facets turned towards each stored azimuth:
    /// each of its nodes reads the light by its own normal.
    lobe_toward: Option<Vec<HorizonToward>>,
    /// Per texel, its pyramid lobes `view[view_start[t]..view_start[t + 1]]` (indexed by the
    /// `src` of [`SgLobe`] and [`Node`]), what view weighting reads of each
    /// ([`NdfMapped::with_view_weighting`]); both empty in tiles built on demand without it.
    view_start: Vec<u32>,
    view: Vec<ViewLobe>,
}

/// One level of the material: its size and its tables, one per tile of `tile × tile` texels
/// (the last row and column of tiles narrower), each built when a shading call first reads
/// it (`NdfMapped::from_pyramid`) or all at once (`NdfMapped::new`, one tile a level).
#[derive(Clone, Debug)]
struct TexLevel {
    /// Texels along x.
    cols: usize,
    /// Texels along y.
    rows: usize,
    /// Level-0 cells a texel spans.
    span: f64,
    /// Side of a tile, in texels.
    tile: usize,
    /// Tiles along x.
    tiles_x: usize,
    /// The tiles, row-major.
    tiles: Vec<Slot>,
}

/// One tile of a level: its tables once built (and until the cache drops them, `TileCache`),
/// and whether a shading call read it since the cache last looked.
#[derive(Debug, Default)]
struct Slot {
    table: Mutex<Option<Arc<NodeLevel>>>,
    used: AtomicBool,
}

impl Slot {
    /// A slot holding `table`.
    fn built(table: NodeLevel) -> Slot {
        Slot {
            table: Mutex::new(Some(Arc::new(table))),
            used: AtomicBool::new(false),
        }
    }
    /// The tables, if built.
    fn get(&self) -> Option<Arc<NodeLevel>> {
        self.table.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

impl Clone for Slot {
    fn clone(&self) -> Slot {
        Slot {
            table: Mutex::new(self.get()),
            used: AtomicBool::new(self.used.load(Ordering::Relaxed)),
        }
    }
}

/// The tiles built on demand and their memory, dropped oldest first (a tile read since the
/// last pass is kept one more) when they pass `cap` bytes.
#[derive(Debug, Default)]
struct TileCache {
    /// Most bytes of tables held (`usize::MAX`: no limit).
    cap: usize,
    state: Mutex<CacheState>,
}

#[derive(Debug, Default, Clone)]
struct CacheState {
    /// Bytes of the tables held.
    bytes: usize,
    /// Most bytes held at once.
    peak: usize,
    /// Tiles built and held, oldest first: (level, tile).
    order: std::collections::VecDeque<(usize, usize)>,
    /// Tiles dropped to stay under the cap.
    dropped: usize,
}

impl Clone for TileCache {
    fn clone(&self) -> TileCache {
        TileCache {
            cap: self.cap,
            state: Mutex::new(self.state.lock().unwrap_or_else(|e| e.into_inner()).clone()),
        }
    }
}

impl NodeLevel {
    /// Bytes of the tables (what the tile cache counts).
    fn bytes(&self) -> usize {
        use std::mem::size_of;
        self.lobe_start.len() * 4
            + self.lobes.len() * size_of::<SgLobe>()
            + self.shapes.len() * size_of::<Shape>()
            + self.node_start.len() * 4
            + self.nodes.len() * size_of::<Node>()
            + self.horizon.as_ref().map_or(0, Horizons::bytes)
            + self
                .lobe_horizon
                .as_ref()
                .map_or(0, |v| v.len() * size_of::<HorizonCdf>())
            + self
                .cells
                .as_ref()
                .map_or(0, |v| v.len() * size_of::<CellHorizon>())
            + self
                .lobe_joint
                .as_ref()
                .map_or(0, |v| v.len() * size_of::<HorizonJoint>())
            + self
                .lobe_toward
                .as_ref()
                .map_or(0, |v| v.len() * size_of::<HorizonToward>())
            + self.view_start.len() * 4
            + self.view.len() * size_of::<ViewLobe>()
            + size_of::<NodeLevel>()
    }
}

impl TexLevel {
    /// Tile `(tr, tc)`'s rows and columns of the level.
    fn tile_rect(&self, i: usize) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
        let (tr, tc) = (i / self.tiles_x, i % self.tiles_x);
        let (r0, c0) = (tr * self.tile, tc * self.tile);
        (
            r0..(r0 + self.tile).min(self.rows),
            c0..(c0 + self.tile).min(self.cols),
        )
    }
}

/// What a lobe is shadowed with: its horizon distribution, on level 0 its cell's horizons,
/// or for [`NO_LOBE`] its texel's horizon statistics.
#[derive(Clone, Copy, Debug, PartialEq)]
enum LobeHorizon<'a> {
    /// A lobe's own ([`meso_maps::lobe_stats_by_cell`]).
    Lobe(&'a HorizonCdf),
    /// The lobe's cell's, on level 0 ([`meso_maps::LobeStats::cells`]).
    Cell(&'a CellHorizon),
    /// The texel's (`Level::horizon`).
    Texel(HorizonStats),
}

impl LobeHorizon<'_> {
    /// The fraction of what it stands for that sees the prepared direction `d`.
    #[inline]
    fn visibility_along(&self, d: &HorizonDirection) -> f64 {
        match self {
            LobeHorizon::Lobe(c) => c.visibility_along(d),
            LobeHorizon::Cell(c) => c.visibility_along(d),
            LobeHorizon::Texel(s) => s.visibility_along(d),
        }
    }
}

/// What a lobe's nodes read of the light: one value for all of them, or each by its own normal
/// (from level [`meso_maps::JOINT_FROM_LEVEL`] on, [`meso_maps::HorizonToward`]).
#[derive(Clone, Copy, Debug)]
enum LobeRead {
    /// The lobe's visibility of the light (given the viewer's, with view weighting).
    Uniform(f64),
    /// Per normal: the light's reading, and with view weighting the lobe's visibility of the
    /// viewer `u` and the dependence `theta` each normal's fraction of the light takes with it.
    Toward {
        light: TowardReading,
        given: Option<Given>,
    },
}

/// With view weighting, what a lobe read per normal ([`LobeRead::Toward`]) holds of the viewer:
/// its visibility `u`, the dependence `theta` each normal's fraction of the light takes with it,
/// and the weight `far` of the reading per normal beside the lobe's own value `own`
/// (`meso_maps::HorizonPair::far_weight`: a light beside the viewer's azimuth is read with it as
/// one event).
#[derive(Clone, Copy, Debug)]
struct Given {
    u: f64,
    theta: f64,
    far: f64,
    own: f64,
}

impl LobeRead {
    /// The visibility of the light of the lobe's facets of unit normal `m`: with view
    /// weighting, among those that see the viewer (their joint fraction over `u`).
    #[inline]
    fn light(&self, m: DVec3) -> f64 {
        match self {
            LobeRead::Uniform(v) => *v,
            LobeRead::Toward { light, given: None } => light.at(m),
            LobeRead::Toward {
                light,
                given: Some(g),
            } => {
                let a = light.at(m);
                let per_normal = if g.u <= 0.0 {
                    a
                } else {
                    (with_frechet_dependence(a, g.u, g.theta) / g.u).min(1.0)
                };
                g.far * per_normal + (1.0 - g.far) * g.own
            }
        }
    }
}

/// The nodes `nodes` of a texel (Lambert and general facets; a lobe's nodes come together) by
/// runs of one `key` (what a lobe reads: its own distribution, or on level 0 its texel's
/// cell): `f(node, its run's reading)`, the reading made by `read` of the run's first lobe
/// when a node of the run first asks for it ([`RunRead::light`]), at most once a run.
#[inline]
fn by_runs<R: Fn(u32) -> LobeRead>(
    nodes: &[Node],
    key: impl Fn(u32) -> (u32, bool),
    read: R,
    mut f: impl FnMut(&Node, &mut RunRead<'_, R>),
) {
    let mut i = 0;
    while i < nodes.len() {
        let k = key(nodes[i].src);
        let mut j = i + 1;
        while j < nodes.len() && key(nodes[j].src) == k {
            j += 1;
        }
        let mut run = RunRead {
            src: nodes[i].src,
            read: &read,
            made: None,
        };
        for nd in &nodes[i..j] {
            f(nd, &mut run);
        }
        i = j;
    }
}

/// A run's reading of the light ([`by_runs`]), made when first asked for.
struct RunRead<'a, R> {
    src: u32,
    read: &'a R,
    made: Option<LobeRead>,
}

impl<R: Fn(u32) -> LobeRead> RunRead<'_, R> {
    /// The visibility of the light of the run's facets of unit normal `m`.
    #[inline]
    fn light(&mut self, m: DVec3) -> f64 {
        let (src, read) = (self.src, self.read);
        self.made.get_or_insert_with(|| read(src)).light(m)
    }
}

/// The readings of the light a texel's lobes have made (at most one per lobe and the texel's
/// own statistics, by the key of what each reads): kept where a texel's lobes are asked in
/// turn more than once (the microfacet facets' core peaks, then their nodes).
struct Readings {
    n: usize,
    keys: [(u32, bool); READINGS],
    reads: [LobeRead; READINGS],
}

/// Most readings [`Readings`] keeps: a texel's lobes and its own statistics ([`NO_LOBE`]).
const READINGS: usize = meso_maps::limits::MAX_LOBES + 1;

impl Readings {
    fn new() -> Readings {
        Readings {
            n: 0,
            keys: [(0, false); READINGS],
            reads: [LobeRead::Uniform(1.0); READINGS],
        }
    }

    /// The visibility of the light of the facets of unit normal `m` of what reads by `key`,
    /// its reading made by `make` the first time the key is asked for.
    #[inline]
    fn light(&mut self, key: (u32, bool), m: DVec3, make: impl FnOnce() -> LobeRead) -> f64 {
        if let Some(i) = self.keys[..self.n].iter().position(|&k| k == key) {
            return self.reads[i].light(m);
        }
        let r = make();
        if self.n < READINGS {
            self.keys[self.n] = key;
            self.reads[self.n] = r;
            self.n += 1;
        }
        r.light(m)
    }
}

impl NodeLevel {
    /// What lobe `src` of texel `t` is shadowed with: the lobe's own distribution (on level 0
    /// its cell's horizons, which all of a texel's lobes stand for), or the texel's statistics
    /// for [`NO_LOBE`]; `None` without shadowing.
    #[inline]
    fn lobe_horizon(&self, t: usize, src: u32) -> Option<LobeHorizon<'_>> {
        let th = self.horizon.as_ref()?;
        if src == NO_LOBE {
            return Some(LobeHorizon::Texel(th.get(t)));
        }
        match (&self.cells, &self.lobe_horizon) {
            (Some(c), _) => Some(LobeHorizon::Cell(&c[t])),
            (None, Some(lh)) => Some(LobeHorizon::Lobe(&lh[src as usize])),
            (None, None) => None,
        }
    }

    /// Lobe `src`'s joint horizon distribution, where the level has them (`None` for
    /// [`NO_LOBE`]).
    #[inline]
    fn lobe_joint(&self, src: u32) -> Option<&HorizonJoint> {
        self.lobe_joint.as_ref()?.get(src as usize)
    }

    /// Lobe `src`'s facets turned towards each stored azimuth, where the level has them
    /// (`None` for [`NO_LOBE`]).
    #[inline]
    fn lobe_toward(&self, src: u32) -> Option<&HorizonToward> {
        self.lobe_toward.as_ref()?.get(src as usize)
    }
}

/// A material reading an NDF pyramid (see the module docs): the filtered bump map.
#[derive(Clone, Debug)]
pub struct NdfMapped {
    levels: Vec<TexLevel>,
    /// The pyramid the tiles not yet built are built from (`NdfMapped::from_pyramid`);
    /// `None` when every tile was built up front (`NdfMapped::new`).
    source: Option<Source>,
    /// The tiles built on demand, under a memory cap.
    cache: TileCache,
    facet: Facet,
    diffuse: [f32; 3],
    texels_per_uv: f64,
    shadowing: bool,
    footprint_scale: f64,
    sharp_magnification: bool,
    box_filter: bool,
    /// Levels finer than the footprint the box filter reads ([`NdfMapped::with_box_detail`]).
    box_detail: f64,
    /// The finest level the box detail may take a footprint to (a footprint whose own level is
    /// finer keeps it): with a table cap, the finest level whose whole tables fit in half the
    /// cap ([`NdfMapped::with_table_cap`]); 0 otherwise.
    detail_floor: usize,
    texel_visibility: bool,
    /// Weight each lobe by the area of it the viewer sees ([`NdfMapped::with_view_weighting`]).
    view_weighting: bool,
    /// This material's id among those constructed ([`TexelMemo`]'s key; a clone shares it, and
    /// its tables).
    memo_id: u64,
    /// Bytes a thread's [`TexelMemo`] may keep of this material: [`MEMO_BYTES`], or under a
    /// table cap half of it shared among the rendering threads, if less.
    memo_cap: usize,
}

/// One light of a shading call, prepared once for the call's taps.
#[derive(Clone, Copy, Debug)]
struct LightPrep {
    /// Its direction in the surface's frame.
    i: DVec3,
    /// Above the surface and not opposite the viewer: shaded.
    lit: bool,
    /// The half vector with the viewer.
    h: DVec3,
    /// The colour of a scalar facet's response to it (a microfacet facet's Fresnel factor).
    colour: [f64; 3],
    /// The light's direction among the horizon statistics (+z without shadowing).
    dir: HorizonDirection,
    /// The light and the viewer prepared together (view weighting per lobe).
    pair: Option<HorizonPair>,
}

/// A shading call's buffers, reused from call to call on each thread: its taps, each tap's
/// entry in the memo, its lights, and the thread's [`TexelMemo`].
#[derive(Debug, Default)]
struct Call {
    taps: Vec<Tap>,
    entries: Vec<usize>,
    lights: Vec<LightPrep>,
    memo: TexelMemo,
}

std::thread_local! {
    /// The thread's [`Call`] buffers.
    static CALL: std::cell::RefCell<Call> = std::cell::RefCell::new(Call::default());
}

/// The tiles a shading call has fetched (the taps of a call share a few): at most two levels,
/// within 2 × 2 tiles on each up to detail 2 (a footprint spans at most 34 texels of a level,
/// a tile 64), 3 × 3 at detail 3: 8 places, more on the heap.
#[derive(Default)]
struct CallTiles {
    held: [(usize, usize, Option<Arc<NodeLevel>>); 8],
    more: Vec<(usize, usize, Option<Arc<NodeLevel>>)>,
    n: usize,
}

impl CallTiles {
    /// The tile holding texel `t` of level `lev` (fetched from `m` on first use) and the
    /// texel's index in it.
    fn get(&mut self, m: &NdfMapped, lev: usize, t: usize) -> (&NodeLevel, usize) {
        let (i, local, _) = m.tile_of(lev, t);
        let h = match self.held[..self.n.min(8)]
            .iter()
            .chain(&self.more)
            .position(|(hl, hi, _)| (*hl, *hi) == (lev, i))
        {
            Some(h) => h,
            None => {
                let e = (lev, i, Some(m.tile(lev, i)));
                if self.n < 8 {
                    self.held[self.n] = e;
                } else {
                    self.more.push(e);
                }
                self.n += 1;
                self.n - 1
            }
        };
        let tile = if h < 8 {
            &self.held[h].2
        } else {
            &self.more[h - 8].2
        };
        (tile.as_deref().expect("fetched above"), local)
    }
}

/// The next material's id for [`TexelMemo`]'s key.
static NEXT_MEMO_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

impl NdfMapped {
    /// The key of this material and its options that change a texel's response, for
    /// [`TexelMemo`].
    fn memo_key(&self) -> u64 {
        (self.memo_id << 3)
            | u64::from(self.shadowing)
            | (u64::from(self.texel_visibility) << 1)
            | (u64::from(self.view_weighting) << 2)
    }

    /// Tile `i` of level `lev` and texel `t`'s index in it: the tile and the texel's index.
    #[inline]
    fn tile_of(&self, lev: usize, t: usize) -> (usize, usize, usize) {
        let l = &self.levels[lev];
        let (r, c) = (t / l.cols, t % l.cols);
        let (tr, tc) = (r / l.tile, c / l.tile);
        let width = ((tc + 1) * l.tile).min(l.cols) - tc * l.tile;
        (
            tr * l.tiles_x + tc,
            (r - tr * l.tile) * width + (c - tc * l.tile),
            width,
        )
    }

    /// The tables of tile `i` of level `lev`, built now if not held (and others dropped if the
    /// cache passes its cap).
    fn tile(&self, lev: usize, i: usize) -> Arc<NodeLevel> {
        let slot = &self.levels[lev].tiles[i];
        slot.used.store(true, Ordering::Relaxed);
        let built = {
            let mut g = slot.table.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(t) = &*g {
                return Arc::clone(t);
            }
            // Built under the slot's lock: a second reader waits for it instead of building it
            // again. No other lock is taken while it is held.
            let t = Arc::new(self.build_tile(lev, i));
            *g = Some(Arc::clone(&t));
            t
        };
        self.account(lev, i, built.bytes());
        built
    }

    /// Count a tile just built and drop the oldest tiles (a tile read since the last pass
    /// gets a second chance) while the cache is over its cap.
    fn account(&self, lev: usize, i: usize, bytes: usize) {
        let mut victims = Vec::new();
        {
            let mut st = self.cache.state.lock().unwrap_or_else(|e| e.into_inner());
            st.bytes += bytes;
            st.peak = st.peak.max(st.bytes);
            st.order.push_back((lev, i));
            let mut passes = 2 * st.order.len();
            while st.bytes > self.cache.cap && passes > 0 {
                passes -= 1;
                let Some((vl, vi)) = st.order.pop_front() else {
                    break;
                };
                let slot = &self.levels[vl].tiles[vi];
                if (vl, vi) != (lev, i) && !slot.used.swap(false, Ordering::Relaxed) {
                    victims.push((vl, vi));
                    // Counted out now; the tables are freed below (or when the last reader
                    // holding them is done).
                    let held = slot.get().map_or(0, |t| t.bytes());
                    st.bytes = st.bytes.saturating_sub(held);
                    st.dropped += 1;
                } else {
                    st.order.push_back((vl, vi));
                }
            }
        }
        for (vl, vi) in victims {
            self.levels[vl].tiles[vi]
                .table
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .take();
        }
    }

    /// Number of tiles held over all levels (each a level's whole table for
    /// [`NdfMapped::new`]; those shading calls have read and the cache kept for
    /// [`NdfMapped::from_pyramid`]).
    #[must_use]
    pub fn tiles_built(&self) -> usize {
        self.levels
            .iter()
            .map(|l| l.tiles.iter().filter(|t| t.get().is_some()).count())
            .sum()
    }

    /// The tile cache's figures: bytes of tables held now, the most held at once (a tile just
    /// built counted before others are dropped for it), and tiles
    /// dropped to stay under its cap ([`NdfMapped::with_table_cap`]); all 0 for
    /// [`NdfMapped::new`], whose tables are not counted.
    #[must_use]
    pub fn table_cache_stats(&self) -> (usize, usize, usize) {
        let st = self.cache.state.lock().unwrap_or_else(|e| e.into_inner());
        (st.bytes, st.peak, st.dropped)
    }

    /// Hold at most `bytes` of tables built on demand ([`NdfMapped::from_pyramid`]), dropping
    /// the oldest (a tile read since the last pass kept one more) to build another: rebuilt
    /// if read again, the same tables. Default: no cap. Tiles of the eager
    /// [`NdfMapped::new`] are not counted.
    ///
    /// The cap also bounds the box filter's detail ([`NdfMapped::with_box_detail`]): it takes a
    /// footprint no finer than the finest level whose whole tables fit in half the cap (or from
    /// which all the levels' tables fit in the cap: a map whose every table fits reads as
    /// [`NdfMapped::new`] of its pyramid, bit for bit; before 2026-12-08 level 0, most of a
    /// map's tables, never fitted in half of a cap of all of them), so that
    /// a far view, which reads every part of the map, does not rebuild tiles the cache has
    /// dropped (a 2048² map under a 1 GiB budget took minutes instead of seconds), and the
    /// texel responses each rendering thread keeps between shading calls that share their
    /// directions (at most [`MEMO_BYTES`]) to half the cap shared among the threads
    /// (`rayon::current_num_threads` when called): at most 1.5 × the cap in all.
    #[must_use]
    pub fn with_table_cap(mut self, bytes: usize) -> NdfMapped {
        self.cache.cap = bytes;
        self.memo_cap = MEMO_BYTES.min(bytes / (2 * rayon::current_num_threads().max(1)));
        self.detail_floor = match &self.source {
            Some(src) => {
                let level = |k: usize| {
                    build::level_tables_bytes(
                        src.pyramid(),
                        k,
                        &self.facet,
                        self.shadowing,
                        self.view_weighting,
                    )
                };
                let n = self.levels.len();
                // The finest level whose tables fit in half the cap, or from which every
                // level's fit in the whole cap (a small map: all of them, so the detail reads
                // level 0, as `NdfMapped::new` of the same pyramid does).
                (0..n)
                    .find(|&k| {
                        level(k) <= (bytes / 2) as u64
                            || (k..n).map(level).sum::<u64>() <= bytes as u64
                    })
                    .unwrap_or(n - 1)
            }
            None => 0,
        };
        self
    }

    /// Number of pyramid levels in use.
    #[must_use]
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// Use only levels `0..=max_level` (coarser footprints read `max_level`). For a tileable
    /// map any level whose texels cover whole periods describes the far field; capping skips
    /// coarse levels whose lobe fit is worse (compare their residuals in `meso map info`).
    #[must_use]
    pub fn with_max_level(mut self, max_level: usize) -> NdfMapped {
        let n = max_level.saturating_add(1).max(1);
        self.levels.truncate(n);
        // The tile cache forgets the tiles of the levels dropped.
        let levels = &self.levels;
        let st = self
            .cache
            .state
            .get_mut()
            .unwrap_or_else(|e| e.into_inner());
        st.order.retain(|&(l, _)| l < n);
        st.bytes = st
            .order
            .iter()
            .filter_map(|&(l, i)| levels[l].tiles[i].get())
            .map(|t| t.bytes())
            .sum();
        self
    }

    /// Below level 0 (footprints under √2 cells) read the cells overlapping a box narrower than
    /// the bilinear tent, down to the single cell under the point (see the module docs), so
    /// that supersampling converges to the bump map's cell averages; the default keeps the
    /// bilinear filter there, which shows magnified cells smoothly instead of as squares.
    #[must_use]
    pub fn with_sharp_magnification(mut self, sharp: bool) -> NdfMapped {
        self.sharp_magnification = sharp;
        self
    }

    /// Filter with a box the size of the sample's footprint (the bounding box of its
    /// ray-differential parallelogram): the texels it overlaps, weighted by overlap, on the
    /// level whose texels are an eighth to a quarter of its longer side at detail 0 (finer by
    /// [`NdfMapped::with_box_detail`]), blended with the next coarser level, so zooming stays
    /// continuous — the default, closer to the supersampled bump map on busy maps (see the
    /// module docs, "Steep maps"). `false`: the trilinear filter, 8 taps per shading call
    /// instead of up to 136 (detail 0), ≈ 1 500 (detail 2, the broad facets' default) or
    /// ≈ 5 300 (detail 3, the glossy ones').
    #[must_use]
    pub fn with_box_filter(mut self, on: bool) -> NdfMapped {
        self.box_filter = on;
        self
    }

    /// How many levels finer than the footprint the box filter reads, `detail ∈ [0,`
    /// [`MAX_BOX_DETAIL`]`]` (clamped; fractional values blend two levels): its texels are
    /// `2^−(2 + detail)` to `2^−(3 + detail)` of the footprint box's longer side, so each unit
    /// costs about 1–3× the shading time of a far view and reads texels of half the side,
    /// whose fitted lobes follow a narrow highlight better. The default is
    /// [`default_box_detail`] of the facet material: 3 for glossy facets (GGX or Beckmann
    /// α ≤ 0.158, Phong η ≥ 80, mirrors), whose narrow highlight the coarse texels' lobes
    /// cannot follow (docs/heightmaps.md, "Glossy facets"), 2 for the others ([`BROAD_BOX_DETAIL`]:
    /// the coarse lobes merge a texel's faces and walls; docs/heightmaps.md, "Broad facets read
    /// two levels finer"). Under a table cap
    /// ([`NdfMapped::with_table_cap`]) the detail takes a footprint no finer than the finest
    /// level whose tables fit in half the cap.
    #[must_use]
    pub fn with_box_detail(mut self, detail: f64) -> NdfMapped {
        if detail.is_finite() {
            self.box_detail = detail.clamp(0.0, MAX_BOX_DETAIL);
        }
        self
    }

    /// The box filter's detail in use ([`NdfMapped::with_box_detail`]).
    #[must_use]
    pub fn box_detail(&self) -> f64 {
        self.box_detail
    }

    /// With shadowing, multiply each texel's response by one visibility of the light for the
    /// whole texel (its `HorizonStats::visibility`, blended over the taps) instead of each
    /// lobe's by its own (the default, see the module docs, "Visibility per lobe"): the model
    /// before 2026-12-03, kept for comparison; it cannot tell bumps from grooves.
    #[must_use]
    pub fn with_texel_visibility(mut self, on: bool) -> NdfMapped {
        self.texel_visibility = on;
        self
    }

    /// With `on`, weight each lobe of the footprint by the area of it that the viewer sees, as
    /// displaced geometry does: its share of the texel's projected area times
    /// `E[(m·o)⁺]/E[m_z⁺]` (its facets' area seen from `o` per unit of projected area, by the
    /// lobe's 7 nodes) times, with shadowing, its visibility of `o` (the lobe's horizon
    /// statistics, as for the light), the footprint's response divided by the sum of those
    /// weights; within a lobe, the response near normal `m` is weighed by `(m·o)⁺/m_z`. A texel of one normal (level 0 magnified) shades as without it;
    /// from afar the response tends to the height map's effective BRDF (`meso gonio`) instead
    /// of the bump map's plain average over the surface, which counts the facets facing away
    /// from the viewer and the hidden ones as if seen ([`crate::mapped`], "View weighting").
    /// Default: on with shadowing (a height map's pyramid), off without (a normal map's, whose
    /// steep facets nothing would mask from the viewer).
    ///
    /// Tiles built on demand ([`NdfMapped::from_pyramid`]) hold what view weighting reads only
    /// when it is on (24 bytes a lobe): turning it on or off drops the tiles built so far.
    #[must_use]
    pub fn with_view_weighting(mut self, on: bool) -> NdfMapped {
        if on != self.view_weighting && self.source.is_some() {
            for level in &mut self.levels {
                for slot in &mut level.tiles {
                    *slot.table.get_mut().unwrap_or_else(|e| e.into_inner()) = None;
                    *slot.used.get_mut() = false;
                }
            }
            let st = self
                .cache
                .state
                .get_mut()
                .unwrap_or_else(|e| e.into_inner());
            st.bytes = 0;
            st.order.clear();
        }
        self.view_weighting = on;
        self
    }

    /// Whether view weighting is on ([`NdfMapped::with_view_weighting`]).
    #[must_use]
    pub fn view_weighting(&self) -> bool {
        self.view_weighting
    }

    /// Multiply the ray-differential footprint by `scale` (> 0; default 1) before choosing the
    /// level of detail (for experiments; the renderer already fits the footprint to each
    /// sample's share of the pixel).
    #[must_use]
    pub fn with_footprint_scale(mut self, scale: f64) -> NdfMapped {
        if scale.is_finite() && scale > 0.0 {
            self.footprint_scale = scale;
        }
        self
    }
    /// The facets' response `E[f_μ(i, o; m) (m·i)⁺]` of texel `t` of level `l` (scalar for
    /// Phong, Lambert and isotropic microfacet facets, whose colour — for microfacets the
    /// Fresnel factor — is applied by the caller), each lobe's part multiplied by its
    /// visibility of the light `wi` (prepared as `dir`) when `dir` is given
    /// and the level has per-lobe horizon statistics, and with `view` by its view weight
    /// ([`TexelView::weight`], which holds the lobe's visibility of the viewer): the light's
    /// visibility is then that of what of the lobe sees the viewer (`pair`: the light and the
    /// viewer prepared together)
    /// ([`meso_maps::HorizonCdf::visibility_given`]), so that the two together are the
    /// lobe's joint visibility, not the product of its two. From
    /// [`meso_maps::JOINT_FROM_LEVEL`] on each node of a lobe reads the light by its own normal
    /// ([`meso_maps::HorizonToward`], `LobeRead`).
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn texel(
        &self,
        l: &NodeLevel,
        t: usize,
        wi: DVec3,
        wo: DVec3,
        h: DVec3,
        dir: Option<&HorizonDirection>,
        view: Option<&TexelView>,
        pair: Option<&HorizonPair>,
    ) -> [f64; 3] {
        // With view weighting, a lobe's visibility of the light among what of it sees the
        // viewer (its view weight holds that part): the two together, not their product. From
        // `JOINT_FROM_LEVEL` on each node reads the light by its own normal.
        let read_of = |src: u32| -> LobeRead {
            match (dir, l.lobe_horizon(t, src)) {
                (Some(d), Some(LobeHorizon::Lobe(c))) => {
                    if let Some(tw) = l.lobe_toward(src) {
                        return match pair {
                            Some(p) => {
                                let far = p.far_weight();
                                if far <= 0.0 {
                                    return LobeRead::Uniform(
                                        c.visibility_given(l.lobe_joint(src), p),
                                    );
                                }
                                // The lobe's own fractions that see the light, the viewer and
                                // both, and [`HorizonCdf::visibility_given`]'s rule of them.
                                let fractions = c.pair_fractions(l.lobe_joint(src), p);
                                let [vl, u, both] = fractions;
                                let own = HorizonCdf::light_given_view(fractions);
                                let light = tw.reading(c, d);
                                if light.is_uniform() {
                                    // Every normal reads alike: the lobe's own.
                                    return LobeRead::Uniform(own);
                                }
                                let theta = frechet_dependence(vl, u, both);
                                LobeRead::Toward {
                                    light,
                                    given: Some(Given { u, theta, far, own }),
                                }
                            }
                            None => LobeRead::Toward {
                                light: tw.reading(c, d),
                                given: None,
                            },
                        };
                    }
                    LobeRead::Uniform(match pair {
                        Some(p) => c.visibility_given(l.lobe_joint(src), p),
                        None => c.visibility_along(d),
                    })
                }
                (Some(d), Some(LobeHorizon::Cell(c))) => LobeRead::Uniform(match pair {
                    Some(p) => c.visibility_given(p),
                    None => c.visibility_along(d),
                }),
                (Some(d), Some(s)) => LobeRead::Uniform(s.visibility_along(d)),
                _ => LobeRead::Uniform(1.0),
            }
        };
        // The key of what lobe `src` reads: its own distribution, or (level 0) its texel's one
        // cell, which every lobe of the texel reads.
        let key = |src: u32| -> (u32, bool) {
            if src != NO_LOBE && l.cells.is_some() {
                (NO_LOBE, true)
            } else {
                (src, false)
            }
        };
        // Asked lobe by lobe and node by node by the microfacet facets (every core peak of
        // every lobe, then the nodes) and by level 0's Phong lobes: each reading is made once
        // and kept for the texel. Set up on first use: the Lambert and general facets read by
        // runs, and Phong lobes above level 0 directly.
        let readings = std::cell::OnceCell::new();
        let vis = |src: u32, m: DVec3| -> f64 {
            readings
                .get_or_init(|| std::cell::RefCell::new(Readings::new()))
                .borrow_mut()
                .light(key(src), m, || read_of(src))
        };
        let seen = |src: u32, m: DVec3| -> f64 {
            match view {
                Some(tv) => tv.weight(src, m),
                None => 1.0,
            }
        };
        match self.facet {
            Facet::Phong { exponent, .. } => {
                let lobes = &l.lobes[l.lobe_start[t] as usize..l.lobe_start[t + 1] as usize];
                let eta = f64::from(exponent);
                [
                    phong_texel(
                        lobes,
                        &l.shapes,
                        wi,
                        h,
                        eta,
                        sg::kappa_transfer(eta),
                        // One reading per lobe: kept for the next lobe only where every lobe
                        // of the texel reads its one cell (level 0).
                        |lb, m| {
                            let v = if l.cells.is_some() {
                                vis(lb.src, m)
                            } else {
                                read_of(lb.src).light(m)
                            };
                            v * seen(lb.src, m)
                        },
                    ),
                    0.0,
                    0.0,
                ]
            }
            Facet::Lambert { .. } => {
                let nodes = &l.nodes[l.node_start[t] as usize..l.node_start[t + 1] as usize];
                let mut a = 0.0;
                by_runs(nodes, key, read_of, |nd, run| {
                    let c = nd.n.dot(wi);
                    if nd.n.dot(wo) > 0.0 && c > 0.0 {
                        a += nd.w * c * run.light(nd.n) * seen(nd.src, nd.n);
                    }
                });
                [a, 0.0, 0.0]
            }
            Facet::Microfacet {
                distribution, core, ..
            } => {
                let lobes = &l.lobes[l.lobe_start[t] as usize..l.lobe_start[t + 1] as usize];
                let nodes = &l.nodes[l.node_start[t] as usize..l.node_start[t + 1] as usize];
                [
                    microfacet_texel(
                        lobes,
                        &l.shapes,
                        nodes,
                        &distribution,
                        core.as_ref(),
                        wi,
                        wo,
                        h,
                        vis,
                        seen,
                    ),
                    0.0,
                    0.0,
                ]
            }
            Facet::General(_) => {
                let nodes = &l.nodes[l.node_start[t] as usize..l.node_start[t + 1] as usize];
                let mut a = [0.0f64; 3];
                by_runs(nodes, key, read_of, |nd, run| {
                    let v = self.facet.lit(nd.n, wi, wo, h);
                    if v == [0.0; 3] {
                        return;
                    }
                    let w = nd.w * run.light(nd.n) * seen(nd.src, nd.n);
                    for c in 0..3 {
                        a[c] += w * f64::from(v[c]);
                    }
                });
                a
            }
        }
    }
}

impl Shader for NdfMapped {
    /// "NDF-mapped: L levels, box filter[ D levels finer[ (no finer than level F under the
    /// table cap)]][, horizon shadowing per lobe | per texel][, view-weighted]" ("trilinear
    /// filter" for the trilinear filter).
    fn describe(&self) -> Option<String> {
        let filter = if !self.box_filter {
            "trilinear filter".to_string()
        } else if self.box_detail > 0.0 {
            // Glossy facets read finer levels than the footprint (`default_box_detail`); a
            // table cap bounds how fine.
            format!(
                "box filter {:.2} levels finer{}",
                self.box_detail,
                if self.detail_floor > 0 {
                    format!(
                        " (no finer than level {} under the table cap)",
                        self.detail_floor
                    )
                } else {
                    String::new()
                }
            )
        } else {
            "box filter".to_string()
        };
        let shadow = match (self.shadowing, self.texel_visibility) {
            (false, _) => "",
            (true, false) => ", horizon shadowing per lobe",
            (true, true) => ", horizon shadowing per texel",
        };
        Some(format!(
            "NDF-mapped: {} levels, {filter}{shadow}{}",
            self.levels.len(),
            if self.view_weighting {
                ", view-weighted"
            } else {
                ""
            }
        ))
    }

    /// The source pyramid's [`meso_maps::Pyramid::check_mapped`] (tables built on demand read
    /// a map file's level 0 as they go); `Ok` for [`NdfMapped::new`].
    fn check_sources(&self) -> Result<(), String> {
        match &self.source {
            Some(s) => s.pyramid().check_mapped().map_err(|e| e.to_string()),
            None => Ok(()),
        }
    }

    fn eval(&self, sp: &ShadingPoint, wi: DVec3, wo: DVec3) -> [f32; 3] {
        let mut out = [[0.0f32; 3]; 1];
        self.eval_many(sp, wo, &[wi], &mut out);
        out[0]
    }

    fn eval_many(&self, sp: &ShadingPoint, wo: DVec3, wi: &[DVec3], out: &mut [[f32; 3]]) {
        for o in out.iter_mut() {
            *o = [0.0; 3];
        }
        if wo.z <= 0.0 {
            return;
        }
        // The colour of a scalar facet's response: its specular or albedo, or for a
        // microfacet facet the Fresnel factor of each light direction (below).
        let base: [f64; 3] = match self.facet {
            Facet::Phong { specular, .. } => specular.map(f64::from),
            Facet::Lambert { albedo_pi } => albedo_pi.map(f64::from),
            Facet::Microfacet { .. } | Facet::General(_) => [1.0; 3],
        };
        let scalar = !matches!(self.facet, Facet::General(_));
        let mut call = CALL.with(|c| std::mem::take(&mut *c.borrow_mut()));
        let Call {
            taps,
            entries,
            lights,
            memo,
        } = &mut call;
        self.taps(sp, taps);
        // Per lobe (the default): each lobe's part times its own visibility; per texel: the
        // response times the taps' blended visibility. The same for the light and the viewer.
        let per_lobe = self.shadowing && !self.texel_visibility;
        // The viewer prepared once a call, with view weighting only.
        let dir_o = self.view_weighting.then(|| HorizonDirection::new(wo));
        // Each light prepared once a call: its half vector, colour, direction and pair.
        lights.clear();
        lights.extend(wi.iter().map(|&i| {
            let s = i + wo;
            let len = s.length();
            let h = s / len;
            let dir = if self.shadowing {
                HorizonDirection::new(i)
            } else {
                HorizonDirection::new(DVec3::Z)
            };
            LightPrep {
                i,
                lit: i.z > 0.0 && len > 1e-12,
                h,
                colour: match self.facet {
                    Facet::Microfacet { fresnel, .. } if i.z > 0.0 && len > 1e-12 => {
                        fresnel.eval(i.dot(h))
                    }
                    _ => base,
                },
                dir,
                // Used only where the footprint is seen (`view_on` below).
                pair: dir_o
                    .as_ref()
                    .filter(|_| per_lobe)
                    .map(|o| HorizonPair::new(&dir, o)),
            }
        }));
        // Each tap's texel's part (`memo`): kept from the thread's last calls if they asked
        // the same directions of this material, made now otherwise.
        memo.begin(self.memo_key(), wo, wi);
        let mut tiles = CallTiles::default();
        entries.clear();
        let mut den = 0.0;
        for &(lev, t, w) in taps.iter() {
            let (e, fresh) = memo.entry(lev, t, self.memo_cap);
            if fresh {
                let (l, t) = tiles.get(self, lev, t);
                let d = &mut memo.data[e..e + memo.stride];
                d[1] = 0.0;
                if let Some(dir_o) = &dir_o {
                    // On level 0 every lobe of the texel reads its one cell: read once.
                    let cell_o = std::cell::OnceCell::new();
                    let tv = TexelView::new(l, t, wo, |src| {
                        if per_lobe {
                            match l.lobe_horizon(t, src) {
                                Some(LobeHorizon::Cell(c)) => {
                                    *cell_o.get_or_init(|| c.visibility_along(dir_o))
                                }
                                s => s.map_or(1.0, |s| s.visibility_along(dir_o)),
                            }
                        } else if self.shadowing {
                            l.horizon
                                .as_ref()
                                .map_or(1.0, |h| h.get(t).visibility_along(dir_o))
                        } else {
                            1.0
                        }
                    });
                    d[0] = tv.den;
                    for (k, lp) in lights.iter().enumerate().filter(|(_, lp)| lp.lit) {
                        let v = self.texel(
                            l,
                            t,
                            lp.i,
                            wo,
                            lp.h,
                            per_lobe.then_some(&lp.dir),
                            Some(&tv),
                            lp.pair.as_ref(),
                        );
                        d[HEAD + PER_LIGHT * k..][..3].copy_from_slice(&v);
                    }
                } else {
                    d[0] = 0.0;
                }
                for (k, lp) in lights.iter().enumerate().filter(|(_, lp)| lp.lit) {
                    d[HEAD + PER_LIGHT * k + 6] = match (&l.horizon, per_lobe) {
                        (Some(hz), false) => hz.get(t).visibility_along(&lp.dir),
                        _ => 0.0,
                    };
                }
            }
            if dir_o.is_some() {
                den += w * memo.data[e];
            }
            entries.push(e);
        }
        // A footprint barely seen reads partly as the plain average, wholly when nothing of it
        // is seen (or without view weighting): `plain_w`, the plain average's weight beside
        // the seen area `den` (`SEEN_FLOOR`).
        let plain_w = if self.view_weighting {
            let total: f64 = taps.iter().map(|&(_, _, w)| w).sum();
            let seen = den / (wo.z * total).max(1e-300);
            SEEN_FLOOR * (1.0 - seen / SEEN_FADE).max(0.0) * wo.z * total
        } else {
            0.0
        };
        let view_on = self.view_weighting && den > 0.0;
        // The plain responses, where read: made once an entry.
        if !view_on || plain_w > 0.0 {
            for (&(lev, t, _), &e) in taps.iter().zip(entries.iter()) {
                if memo.data[e + 1] == 1.0 {
                    continue;
                }
                let (l, t) = tiles.get(self, lev, t);
                let d = &mut memo.data[e..e + memo.stride];
                for (k, lp) in lights.iter().enumerate().filter(|(_, lp)| lp.lit) {
                    let p = self.texel(
                        l,
                        t,
                        lp.i,
                        wo,
                        lp.h,
                        per_lobe.then_some(&lp.dir),
                        None,
                        None,
                    );
                    d[HEAD + PER_LIGHT * k + 3..][..3].copy_from_slice(&p);
                }
                d[1] = 1.0;
            }
        }
        for (k, lp) in lights.iter().enumerate().filter(|(_, lp)| lp.lit) {
            let mut acc = [0.0f64; 3];
            let mut vis = 0.0f64;
            for (&(_, _, w), &e) in taps.iter().zip(entries.iter()) {
                let d = &memo.data[e + HEAD + PER_LIGHT * k..][..PER_LIGHT];
                let mut v = if view_on {
                    [d[0], d[1], d[2]]
                } else {
                    [d[3], d[4], d[5]]
                };
                if view_on && plain_w > 0.0 {
                    // The plain average's part: `(Σ w·seen·L + plain_w · Σ w·L) / (den +
                    // plain_w)`.
                    for c in 0..3 {
                        v[c] += plain_w * d[3 + c];
                    }
                }
                if scalar {
                    acc[0] += w * v[0];
                } else {
                    for c in 0..3 {
                        acc[c] += w * v[c];
                    }
                }
                if !per_lobe {
                    vis += w * d[6];
                }
            }
            let v = if self.shadowing && !per_lobe {
                vis
            } else {
                1.0
            };
            let s = if view_on {
                v / (lp.i.z * (den + plain_w))
            } else {
                v / lp.i.z
            };
            for c in 0..3 {
                let a = if scalar {
                    acc[0] * lp.colour[c]
                } else {
                    acc[c]
                };
                out[k][c] = (a * s) as f32 + self.diffuse[c];
            }
        }
        // The buffers back for the thread's next call.
        CALL.with(|c| *c.borrow_mut() = call);
    }
}
