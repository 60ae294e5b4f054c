//! Texel responses kept from one shading call to the next on a thread ([`TexelMemo`]), for
//! the calls that share their directions exactly.
//!
//! A texel's part of a shading call — its view weight, its response to each light with and
//! without the viewer's weight, its visibility of each light — depends on the texel and on the
//! light and viewing directions in the surface's frame, not on where the call lands in it.
//! Under an orthographic camera and directional lights, a flat surface asks every pixel with
//! the same directions, bit for bit, and a far view's box filter reads each texel for every
//! pixel whose footprint holds it (at 64 cells a pixel and box detail 3, each texel of a
//! tiled map about a thousand times): kept, each is computed once a thread. The sums over a
//! call's taps are made as before, in the same order, so the image is the same bit for bit.
//! Calls whose directions change from one to the next (a perspective camera, a curved
//! surface, point lights) keep nothing and pay one comparison of directions a call.
//!
//! # Conventions
//! * An entry is `stride` floats: the texel's view weight, a flag (1 when its responses
//!   without the viewer's weight are made), then per light [`PER_LIGHT`] floats: the response
//!   with the viewer's weight (3), without it (3), the texel's visibility of the light (per
//!   texel shadowing).
//! * Keys are `(level, texel)`; the directions, the material (an id per constructed material)
//!   and its options that change a texel's response are the memo's key, one at a time.

use rustc_hash::FxHashMap;

/// Bytes of kept entries a rendering thread holds at most for an NDF-mapped material (their
/// floats and their index; less under a table cap, [`crate::NdfMapped::with_table_cap`]);
/// entries past it are made for the call only.
pub const MEMO_BYTES: usize = 16 << 20;

/// Floats of one light's part of an entry (module docs).
pub(super) const PER_LIGHT: usize = 7;

/// Floats of an entry before its lights' parts: the view weight and the "made without the
/// viewer's weight" flag.
pub(super) const HEAD: usize = 2;

/// Bytes an entry's index costs beside its floats: key and slot (16) and the hash table's
/// control byte and spare buckets (at most 8/7, before the doubling counted in `entry`).
const INDEX_BYTES: usize = 24;

/// What the entries were made for: the material, its options and the directions.
#[derive(Debug, Default, PartialEq)]
struct Key {
    material: u64,
    wo: [u64; 3],
    wi: Vec<[u64; 3]>,
}

impl Key {
    /// Whether the key is `material`, `wo` and `wi`, bit for bit.
    fn is(&self, material: u64, wo: glam::DVec3, wi: &[glam::DVec3]) -> bool {
        self.material == material
            && self.wo == bits(wo)
            && self.wi.len() == wi.len()
            && self.wi.iter().zip(wi).all(|(a, &b)| *a == bits(b))
    }

    /// Make the key `material`, `wo` and `wi` (no allocation once the lights' room is there).
    fn set(&mut self, material: u64, wo: glam::DVec3, wi: &[glam::DVec3]) {
        self.material = material;
        self.wo = bits(wo);
        self.wi.clear();
        self.wi.extend(wi.iter().map(|&w| bits(w)));
    }
}

/// A direction's bits.
fn bits(v: glam::DVec3) -> [u64; 3] {
    [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]
}

/// A thread's kept texel responses (module docs): entries in one flat array, kept ones first,
/// then the current call's own.
#[derive(Debug, Default)]
pub(super) struct TexelMemo {
    key: Key,
    /// The last two calls shared the key: entries are kept.
    armed: bool,
    /// `(level, texel)` → offset of its entry in `data`.
    slots: FxHashMap<u64, u32>,
    /// The entries.
    pub(super) data: Vec<f64>,
    /// Floats of the kept entries (the rest are the current call's).
    kept: usize,
    /// Floats an entry.
    pub(super) stride: usize,
    /// Entries found kept and entries made, since the thread started.
    pub(super) counts: (u64, u64),
}

impl TexelMemo {
    /// Start a call of `material` with `wo` and `wi`: the kept entries stay if the key is the
    /// last call's (and are kept from now on if the last call was the first with it); otherwise
    /// they are dropped and the key becomes this call's.
    pub(super) fn begin(&mut self, material: u64, wo: glam::DVec3, wi: &[glam::DVec3]) {
        let stride = HEAD + PER_LIGHT * wi.len();
        // (The key holds the lights, so a key kept holds the stride too.)
        if self.key.is(material, wo, wi) {
            if !self.armed {
                self.armed = true;
                self.slots.clear();
                self.kept = 0;
            }
        } else {
            self.key.set(material, wo, wi);
            self.armed = false;
            if self.kept > 0 || !self.slots.is_empty() {
                self.slots.clear();
                self.kept = 0;
            }
            self.stride = stride;
        }
        self.data.truncate(self.kept);
    }

    /// The entry of texel `t` of level `lev` for this call: its offset in `data` and whether
    /// it was just made (its floats NaN, to be filled by the caller before the next entry is
    /// asked for) — kept while the memo is armed and under `cap`, the call's own
    /// otherwise.
    /// `cap`: the bytes the kept entries may take ([`MEMO_BYTES`] at most).
    pub(super) fn entry(&mut self, lev: usize, t: usize, cap: usize) -> (usize, bool) {
        let at = self.data.len();
        if self.armed {
            let key = ((lev as u64) << 40) | t as u64;
            if let Some(&o) = self.slots.get(&key) {
                self.counts.0 += 1;
                return (o as usize, false);
            }
            // Twice the entries' bytes: the array and the index grow by doubling, so what they
            // hold is at most twice what they use.
            let room = 2 * ((at + self.stride) * 8 + (self.slots.len() + 1) * INDEX_BYTES);
            // Kept only while the kept entries are all there is (no call's own among them) and
            // the offset fits the index.
            if self.kept == at && room <= cap.min(MEMO_BYTES) && at <= u32::MAX as usize {
                self.slots.insert(key, at as u32);
                self.data.resize(at + self.stride, f64::NAN);
                self.kept = self.data.len();
                self.counts.1 += 1;
                return (at, true);
            }
        }
        self.data.resize(at + self.stride, f64::NAN);
        self.counts.1 += 1;
        (at, true)
    }
}

#[cfg(test)]
mod tests {
    use super::super::{NdfMapped, CALL};
    use super::*;
    use crate::shader::{local_point, Shader};
    use glam::{DVec2, DVec3};
    use meso_core::material::Material;
    use meso_maps::{extract, fixtures, ExtractParams, Source};

    /// Shading calls that find their texels kept shade bit for bit as calls that make them:
    /// the same points read once each after a call with another viewer (nothing kept) and
    /// all in a row (kept from the second call on), for GGX α = 0.1 (box detail 3), Lambert
    /// and Phong facets, with and without shadowing, per lobe and per texel, view weighting
    /// on and off, four lights (one below the horizon), footprints from under a cell to the
    /// whole map; most of the second pass's texels are found kept.
    #[test]
    fn kept_responses_shade_as_made_ones() {
        let map = fixtures::gaussian(64, 3.0, 0.3, 5, 0.02).unwrap();
        let pyr = extract(
            Source::Heights(&map),
            &ExtractParams::default(),
            &mut |_| {},
        )
        .unwrap();
        let wi: Vec<DVec3> = [(0.3, 0.4), (-0.6, 0.1), (0.05, -0.8), (0.2, 0.3)]
            .iter()
            .map(|&(x, y)| {
                let z = (1.0f64 - x * x - y * y).sqrt();
                // The last light below the horizon.
                DVec3::new(x, y, if x == 0.2 { -z } else { z })
            })
            .collect();
        let wo = DVec3::new(-0.2, 0.5, 0.84).normalize();
        let other = DVec3::new(-0.2, 0.5, 0.85).normalize();
        let tpu = 64.0;
        let points: Vec<_> = (0..300u32)
            .map(|i| {
                let f = f64::from(i);
                let uv = DVec2::new((f * 0.618_034).fract(), (f * 0.414_214).fract());
                // Footprints 2⁻² … 2⁷ cells.
                local_point(uv, (2.0f64).powf(-2.0 + 9.0 * (f * 0.7548).fract()) / tpu)
            })
            .collect();
        for transfer in [
            "kind = \"microfacet\"\ndistribution = \"ggx\"\nalpha = 0.1",
            "kind = \"lambert\"",
            "kind = \"phong\"\nexponent = 20.0",
        ] {
            let surface = Material::from_toml_str(&format!("[transfer]\n{transfer}\n")).unwrap();
            for (shadowing, texel_vis, view) in [
                (true, false, true),
                (true, false, false),
                (true, true, true),
                (false, false, false),
                (false, false, true),
            ] {
                let m = NdfMapped::new(&pyr, &surface, tpu, shadowing)
                    .unwrap()
                    .with_texel_visibility(texel_vis)
                    .with_view_weighting(view);
                let (mut a, mut b) = (vec![[0.0f32; 3]; 4], vec![[0.0f32; 3]; 4]);
                let made: Vec<_> = points
                    .iter()
                    .map(|sp| {
                        m.eval_many(sp, other, &wi, &mut b);
                        m.eval_many(sp, wo, &wi, &mut a);
                        a.clone()
                    })
                    .collect();
                let before = CALL.with(|c| c.borrow().memo.counts);
                for (sp, want) in points.iter().zip(&made) {
                    m.eval_many(sp, wo, &wi, &mut a);
                    for (x, y) in a.iter().zip(want) {
                        for ch in 0..3 {
                            assert_eq!(x[ch].to_bits(), y[ch].to_bits(), "{transfer}");
                        }
                    }
                }
                assert!(made.iter().any(|v| v[0][0] > 0.0) && made.iter().all(|v| v[3][0] == 0.0));
                let after = CALL.with(|c| c.borrow().memo.counts);
                let (found, fresh) = (after.0 - before.0, after.1 - before.1);
                assert!(found > fresh, "{transfer}: {found} found, {fresh} made");
            }
        }
    }

    /// Entries are kept from the second call with the same key on, found again after, and
    /// dropped when the key changes; a call's own entries never outlive it.
    #[test]
    fn entries_are_kept_only_while_the_directions_repeat() {
        let mut m = TexelMemo::default();
        let (wo, wi) = (DVec3::new(0.0, 0.6, 0.8), [DVec3::Z]);
        m.begin(7, wo, &wi);
        assert_eq!(m.entry(0, 5, MEMO_BYTES), (0, true));
        m.data[..m.stride].fill(1.0);
        // Second call, same key: armed, the first call's entry is gone.
        m.begin(7, wo, &wi);
        assert_eq!(m.data.len(), 0);
        assert_eq!(m.entry(0, 5, MEMO_BYTES), (0, true));
        m.data[..m.stride].fill(2.0);
        // Third call: found.
        m.begin(7, wo, &wi);
        assert_eq!(m.entry(0, 5, MEMO_BYTES), (0, false));
        assert_eq!(m.data[0], 2.0);
        let (o, fresh) = m.entry(1, 5, MEMO_BYTES);
        assert!(fresh && o == m.stride);
        // Another material, another viewer or another light: nothing kept.
        for (id, o, i) in [
            (8, wo, DVec3::Z),
            (7, DVec3::new(0.0, 0.6000000000000001, 0.8), DVec3::Z),
            (7, wo, DVec3::new(0.0, 0.0, -1.0)),
        ] {
            for _ in 0..2 {
                m.begin(7, wo, &wi);
            }
            let (o0, fresh) = m.entry(2, 9, MEMO_BYTES);
            m.data[o0..o0 + m.stride].fill(3.0);
            m.begin(7, wo, &wi);
            assert_eq!((m.entry(2, 9, MEMO_BYTES), fresh), ((o0, false), true));
            m.begin(id, o, &[i]);
            assert_eq!(m.entry(2, 9, MEMO_BYTES), (0, true));
        }
        // Under a cap of 4 KiB: entries are kept while twice their bytes fit, then made for
        // the call only, and dropped with it.
        for _ in 0..2 {
            m.begin(9, wo, &wi);
        }
        let cap = 4096;
        for t in 0..100 {
            let (o, _) = m.entry(0, t, cap);
            m.data[o..o + m.stride].fill(1.0);
        }
        let kept = m.kept;
        assert!(kept > 0 && 2 * (kept * 8 + m.slots.len() * INDEX_BYTES) <= cap);
        assert!(m.data.len() == kept + (100 - m.slots.len()) * m.stride);
        m.begin(9, wo, &wi);
        assert_eq!(m.data.len(), kept);
        assert!(!m.entry(0, 0, cap).1 && m.entry(0, 99, cap).1);
    }
}
