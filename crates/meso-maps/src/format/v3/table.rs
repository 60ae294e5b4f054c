//! The level table of format 3 (module docs of `v3`): per level its size, lobe count and
//! residuals, read back checked against the header's size and lobe limit; and the memory of
//! the pyramid a table describes (format 4 builds the same table from its level end records).

use crate::compact::COMPACT_TEXELS;
use crate::error::Result;
use crate::format::{Header, Reader, LEVEL_HEADER_BYTES};
use crate::pyramid::Residual;

/// Bytes in memory of one `f64` lobe (`PhongLobe`) and of one texel's `f64` horizon statistics
/// (eight azimuths, 136; half on the levels kept in `f32`, `crate::compact`).
const LOBE_MEM: u64 = 40;
const HORIZON_MEM: u64 = 136;
/// One entry of a format-3 level table, with where the level starts among all texels.
#[derive(Clone, Copy)]
pub(in crate::format) struct TableEntry {
    pub(in crate::format) cols: usize,
    pub(in crate::format) rows: usize,
    pub(in crate::format) span: usize,
    pub(in crate::format) lobes: usize,
    pub(in crate::format) residual: Residual,
    /// Index of the level's first texel among the pyramid's texels.
    pub(in crate::format) t0: usize,
}

impl TableEntry {
    pub(in crate::format) fn texels(&self) -> usize {
        self.cols * self.rows
    }
    /// Whether the level is kept in `f32` in memory ([`COMPACT_TEXELS`]).
    pub(in crate::format) fn compact(&self) -> bool {
        self.texels() >= COMPACT_TEXELS
    }
}

/// The memory (bytes) of the pyramid a level table describes: per lobe 40 bytes (`f64`) or 20
/// (`f32` levels), per texel a lobe start (4) and with horizon statistics 136 or 68.
pub(in crate::format) fn pyramid_bytes(table: &[TableEntry], has_h: bool) -> u64 {
    table
        .iter()
        .map(|t| {
            let (lobe, hz) = if t.compact() {
                (LOBE_MEM / 2, HORIZON_MEM / 2)
            } else {
                (LOBE_MEM, HORIZON_MEM)
            };
            t.lobes as u64 * lobe + t.texels() as u64 * (4 + if has_h { hz } else { 0 })
        })
        .sum()
}

/// The level table (checked against `cols × rows` and `max_lobes`), with the pyramid's total
/// texels and lobes.
pub(super) fn read_table(r: &mut Reader<'_>, h: &Header) -> Result<(Vec<TableEntry>, u64, u64)> {
    let (cols, rows, nlev, max_lobes) = (h.cols, h.rows, h.nlev, h.max_lobes);
    if ((r.b.len() - r.pos) as u64) < nlev as u64 * LEVEL_HEADER_BYTES {
        return Err(r.err("truncated in the level table".into()));
    }
    let mut table = Vec::with_capacity(nlev);
    let (mut ec, mut er) = (cols, rows);
    let (mut texels, mut lobes) = (0u64, 0u64);
    for k in 0..nlev {
        let nl = r.level_header(k, ec, er, max_lobes)?;
        let residual = r.residual()?;
        table.push(TableEntry {
            cols: ec,
            rows: er,
            span: 1usize << k,
            lobes: nl,
            residual,
            t0: texels as usize,
        });
        texels += (ec * er) as u64;
        lobes += nl as u64;
        ec = ec.div_ceil(2);
        er = er.div_ceil(2);
    }
    Ok((table, texels, lobes))
}
