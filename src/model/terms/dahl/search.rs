//! The search of the `dahl` element's rate: the element at several candidate rates replayed
//! side by side over a log ([`DahlSearch`]), with its vectorised kernels.

use super::{DahlTerm, FAR_TABLE, quantise};
use crate::model::term::SearchBasis;

/// Candidate rates run side by side by [`DahlSearch`] (one AVX2 register pair, or one AVX-512
/// register): their chains are independent, so the CPU overlaps them.
const LANES: usize = 8;

/// Log rows per block of [`DahlSearch`]: short, so the CPU overlaps one block's chains with the
/// sums the fit takes of the block before (the 18 candidate batches of `fit --model dahl` on
/// 1M rows, thread CPU: 146 ms with blocks of 256 rows, 122 ms with 32; 16 a few ms less).
const SEARCH_ROWS: usize = 16;

/// The searched element's [`SearchBasis`]: the element at several rates replayed side by side.
/// Keeps each row's signed seek length and whether it is measured (9 bytes a row). Per block of
/// [`SEARCH_ROWS`] rows, one pass the compiler vectorises finds each seek's table index, whether
/// its length is on the table (an integer below the table's length) and its sign, once for
/// every rate; then one loop runs the [`LANES`] chains `G ← s + (G − s)·d` together, `d = r^|dx|`
/// read for all of them from one row of an interleaved table (`table[n·LANES + c] = r_c^n`).
/// A length off the table takes `exp(ln r · |dx|)`, as [`DahlState::peek`] does. The
/// arithmetic is [`DahlTermState`]'s (so the same bits, tested), compiled for AVX2 when the CPU
/// has it (no fused multiply-add either way).
#[derive(Debug)]
pub(super) struct DahlSearch<'d> {
    pub(super) term: DahlTerm,
    /// Target position of every row of the log (position unit), in log order.
    pub(super) tracks: &'d [f64],
    /// The bias column as stored (NaN: not measured).
    pub(super) bias: &'d [f64],
    /// Entries of the power table: one more than the longest integer seek below
    /// [`FAR_TABLE`] in the log.
    pub(super) table_len: usize,
}

impl SearchBasis for DahlSearch<'_> {
    fn replay(&self, values: &[f64], sink: &mut dyn FnMut(&[f64], usize)) -> Option<()> {
        if !self.term.search {
            return None;
        }
        let k = values.len();
        // Per group of LANES rates: ln r of each (the unused lanes repeat the first), its table
        // and its chain state.
        let groups: Vec<([f64; LANES], Vec<f64>)> = values
            .chunks(LANES)
            .map(|vals| {
                let ln_r: [f64; LANES] = std::array::from_fn(|c| {
                    -1.0 / self
                        .term
                        .length_at(vals[if c < vals.len() { c } else { 0 }])
                });
                let mut table = vec![0.0; self.table_len * LANES];
                for (n, row) in table.chunks_exact_mut(LANES).enumerate() {
                    for (t, l) in row.iter_mut().zip(&ln_r) {
                        *t = (l * n as f64).exp();
                    }
                }
                (ln_r, table)
            })
            .collect();
        let mut states = vec![[0.0f64; LANES]; groups.len()];
        let mut idx = [0u32; SEARCH_ROWS];
        let mut sign = [0.0f64; SEARCH_ROWS];
        let mut len = [0.0f64; SEARCH_ROWS];
        let mut chain = vec![[0.0f64; LANES]; SEARCH_ROWS];
        let mut out = vec![0.0; SEARCH_ROWS * k];
        let mut dx_buf = Vec::with_capacity(SEARCH_ROWS);
        for (start, bias) in (0..self.tracks.len())
            .step_by(SEARCH_ROWS)
            .zip(self.bias.chunks(SEARCH_ROWS))
        {
            let m = bias.len();
            let dx = seek_lengths(self.tracks, start, m, &mut dx_buf);
            let measured = bias.iter().map(|b| !b.is_nan());
            let off_table = seek_codes(
                dx,
                self.table_len,
                &mut idx[..m],
                &mut sign[..m],
                &mut len[..m],
            );
            let mut rows = 0;
            for (q, ((ln_r, table), g)) in groups.iter().zip(&mut states).enumerate() {
                let chain = &mut chain[..m];
                if off_table {
                    chain_off_table(g, ln_r, table, &idx[..m], &sign[..m], &len[..m], chain);
                } else {
                    chain_on_table(g, table, &idx[..m], &sign[..m], chain);
                }
                let lanes = LANES.min(k - q * LANES);
                rows = 0;
                for (gs, _) in chain.iter().zip(measured.clone()).filter(|(_, m)| *m) {
                    out[rows * k + q * LANES..rows * k + q * LANES + lanes]
                        .copy_from_slice(&gs[..lanes]);
                    rows += 1;
                }
            }
            if rows > 0 {
                sink(&out[..rows * k], rows);
            }
        }
        Some(())
    }
    fn effective_value(&self, value: f64) -> f64 {
        // `with_nonlinear` sets the length from the quantised coordinate alone.
        quantise(value)
    }
}

/// The seek lengths of rows `start..start + m` of a log with target positions `tracks`, into
/// `buf`: `tracks[i] − tracks[i − 1]`, and 0 for the first row (`target − source`, as
/// `History` computes `seek_length`).
fn seek_lengths<'b>(tracks: &[f64], start: usize, m: usize, buf: &'b mut Vec<f64>) -> &'b [f64] {
    buf.clear();
    buf.extend((start..start + m).map(|i| tracks[i] - tracks[i.saturating_sub(1)]));
    buf
}

/// For each seek length of `dx`: the index into a power table of `table_len` (≤ 4096) entries
/// (`idx`), the sign of the seek (`sign`: 1, −1, or 0 for zero and NaN) and |dx| (`len`, NaN as
/// 0: the identity, as [`DahlState::peek`] leaves a NaN seek). Returns whether any length is
/// off the table (not an integer below `table_len`); for those `idx` is some valid index.
fn seek_codes(
    dx: &[f64],
    table_len: usize,
    idx: &mut [u32],
    sign: &mut [f64],
    len: &mut [f64],
) -> bool {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        return unsafe { seek_codes_avx2(dx, table_len, idx, sign, len) };
    }
    seek_codes_portable(dx, table_len, idx, sign, len)
}

/// [`seek_codes`] compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn seek_codes_avx2(
    dx: &[f64],
    table_len: usize,
    idx: &mut [u32],
    sign: &mut [f64],
    len: &mut [f64],
) -> bool {
    seek_codes_portable(dx, table_len, idx, sign, len)
}

/// [`seek_codes`] for any CPU (a loop the compiler vectorises).
#[inline(always)]
fn seek_codes_portable(
    dx: &[f64],
    table_len: usize,
    idx: &mut [u32],
    sign: &mut [f64],
    len: &mut [f64],
) -> bool {
    // 2^52: for 0 ≤ a < 4096, the low bits of a + 2^52 hold a rounded to an integer, and
    // (a + 2^52) − 2^52 equals a exactly when a is an integer.
    const MAGIC: f64 = 4_503_599_627_370_496.0;
    let top = table_len.clamp(1, FAR_TABLE) as f64 - 1.0;
    let mut off_table = false;
    for (((i, s), l), &d) in idx
        .iter_mut()
        .zip(sign.iter_mut())
        .zip(len.iter_mut())
        .zip(dx)
    {
        let a = d.abs();
        let a = if a > 0.0 { a } else { 0.0 };
        let t = if a < top { a } else { top } + MAGIC;
        off_table |= (t - MAGIC - a).abs() > 0.0;
        *i = (t.to_bits() & (FAR_TABLE as u64 - 1)) as u32;
        *s = if d > 0.0 { 1.0 } else { 0.0 } - if d < 0.0 { 1.0 } else { 0.0 };
        *l = a;
    }
    off_table
}

/// The chains of one group of rates over a block whose seek lengths are all on the table:
/// `G ← s + (G − s)·table[idx]` per lane, each row's states written to `chain`.
fn chain_on_table(
    g: &mut [f64; LANES],
    table: &[f64],
    idx: &[u32],
    sign: &[f64],
    chain: &mut [[f64; LANES]],
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        return unsafe { chain_on_table_avx2(g, table, idx, sign, chain) };
    }
    chain_on_table_portable(g, table, idx, sign, chain);
}

/// [`chain_on_table`] compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn chain_on_table_avx2(
    g: &mut [f64; LANES],
    table: &[f64],
    idx: &[u32],
    sign: &[f64],
    chain: &mut [[f64; LANES]],
) {
    chain_on_table_portable(g, table, idx, sign, chain);
}

/// [`chain_on_table`] for any CPU.
#[inline(always)]
fn chain_on_table_portable(
    g: &mut [f64; LANES],
    table: &[f64],
    idx: &[u32],
    sign: &[f64],
    chain: &mut [[f64; LANES]],
) {
    let mut st = *g;
    for ((out, &i), &s) in chain.iter_mut().zip(idx).zip(sign) {
        let at = i as usize * LANES;
        let d: &[f64; LANES] = table
            .get(at..at + LANES)
            .and_then(|r| r.try_into().ok())
            .unwrap_or(&[1.0; LANES]);
        for c in 0..LANES {
            st[c] = s + (st[c] - s) * d[c];
        }
        *out = st;
    }
    *g = st;
}

/// [`chain_on_table`] for a block with lengths off the table: those rows take
/// `exp(ln r · |dx|)` per lane.
fn chain_off_table(
    g: &mut [f64; LANES],
    ln_r: &[f64; LANES],
    table: &[f64],
    idx: &[u32],
    sign: &[f64],
    len: &[f64],
    chain: &mut [[f64; LANES]],
) {
    let mut st = *g;
    for (((out, &i), &s), &a) in chain.iter_mut().zip(idx).zip(sign).zip(len) {
        let at = i as usize * LANES;
        let on = (i as f64 - a).abs() <= 0.0;
        let d: [f64; LANES] = match table.get(at..at + LANES) {
            Some(row) if on => std::array::from_fn(|c| row[c]),
            _ => std::array::from_fn(|c| (ln_r[c] * a).exp()),
        };
        for c in 0..LANES {
            st[c] = s + (st[c] - s) * d[c];
        }
        *out = st;
    }
    *g = st;
}
