//! The state of a discrete Preisach model: its grid of relay thresholds ([`PreisachGrid`]), the
//! memory staircase of dominant extrema with the wiping-out rule ([`PreisachMemory`]) and the
//! allocation-free predictor that sums the relays through the Everett table
//! ([`PreisachPredictor`]).
//!
//! **Grid.** Levels `t_k = lo + k·h`, `h = (hi − lo)/N`, `k = 0..=N`. Relay `(i, j)`,
//! `0 ≤ j ≤ i < N`, switches up when the input reaches `α_i = t_{i+1}` (x ≥ α) and down when it
//! reaches `β_j = t_j` (x ≤ β): N(N+1)/2 relays, the cells `[t_j, t_{j+1}] × [t_i, t_{i+1}]` of
//! the (β, α) half-plane `α ≥ β` (the diagonal cells `i = j` are its triangles). An input `x`
//! is read as `u = (x − lo)·N/(hi − lo)`: it switches up every α-line `i < U = ⌊u⌋` and down
//! every β-column `j ≥ D = ⌈u⌉` (both clamped to `0..=N`).
//!
//! **Memory.** The relays' states form a staircase, kept as the alternating sequence of the
//! switching operations that still decide a relay: `Down(0)` (every relay down) at the bottom,
//! then `Up(U₁), Down(D₁), Up(U₂), Down(D₂), …` with `U₁ > U₂ > …` and `D₁ < D₂ < …` — the
//! dominant maxima and minima of the input. A new input pops the entries it dominates (the
//! wiping-out rule: exceeding a stored maximum erases it and the minimum after it), so a step
//! costs O(entries popped + 1), at most `2N + 2` entries are held, and nothing is allocated.
//! Relay `(i, j)` is up iff `j < B(i)`, where `B(i) = min(i + 1, D_k)` for the newest `Up(U_k)`
//! with `i < U_k` (`D_k` the `Down` after it, `N` if none) and `B(i) = 0` where there is none.
//!
//! **First input.** The memory starts demagnetised around the first input `x₀`: relay `(i, j)`
//! up iff its midpoint `(α_i + β_j)/2` lies below `x₀` (`i + j + 1 < 2u₀`), the state a long
//! decaying oscillation about `x₀` leaves and the one in which a play operator starts
//! (`z₀ = x₀`), so that `play:N` is a special case from the first row on.

/// The largest N of `preisach:N`.
pub const MAX_LEVELS: usize = 32;

/// Entries the memory holds at most.
const CAPACITY: usize = 2 * MAX_LEVELS + 2;

/// The grid of relay thresholds (see the module docs), in the log's position unit.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PreisachGrid {
    /// The lowest level `t_0` (the least position of the training log).
    pub lo: f64,
    /// The highest level `t_N` (the greatest position of the training log).
    pub hi: f64,
    /// N, the number of α-lines and β-columns (1 to [`MAX_LEVELS`]).
    pub levels: usize,
}

impl PreisachGrid {
    /// Whether the grid is usable: finite `lo < hi`, `1 ≤ N ≤` [`MAX_LEVELS`].
    pub fn is_valid(&self) -> bool {
        self.lo.is_finite()
            && self.hi.is_finite()
            && self.lo < self.hi
            && (1..=MAX_LEVELS).contains(&self.levels)
    }

    /// Number of relays, N(N+1)/2.
    pub fn cells(&self) -> usize {
        self.levels * (self.levels + 1) / 2
    }

    /// Every relay `(i, j)` (`j ≤ i`) of the grid, in row-major triangle order (the order of
    /// [`PreisachGrid::cell`]).
    pub fn relays(&self) -> impl Iterator<Item = (u8, u8)> + use<> {
        (0..self.levels).flat_map(|i| (0..=i).map(move |j| (i as u8, j as u8)))
    }

    /// Index of relay `(i, j)` (`j ≤ i`) in row-major triangle order.
    pub fn cell(i: usize, j: usize) -> usize {
        i * (i + 1) / 2 + j
    }

    /// The input in level units, `u = (x − lo)·N/(hi − lo)` (the arithmetic the C export repeats).
    #[inline(always)]
    pub fn level(&self, x: f64) -> f64 {
        (x - self.lo) * self.levels as f64 / (self.hi - self.lo)
    }

    /// `(U, D)` of an input: it switches up the α-lines `i < U` and down the β-columns `j ≥ D`.
    #[inline(always)]
    pub fn switches(&self, x: f64) -> (u8, u8) {
        let u = self.level(x);
        let n = self.levels as f64;
        // `max`/`min` also send a NaN to 0.
        let up = u.floor().max(0.0).min(n) as u8;
        let down = u.ceil().max(0.0).min(n) as u8;
        (up, down)
    }

    /// Up threshold α_i = t_{i+1} of α-line `i`.
    pub fn alpha(&self, i: usize) -> f64 {
        self.lo + (i + 1) as f64 * (self.hi - self.lo) / self.levels as f64
    }

    /// Down threshold β_j = t_j of β-column `j`.
    pub fn beta(&self, j: usize) -> f64 {
        self.lo + j as f64 * (self.hi - self.lo) / self.levels as f64
    }
}

/// The memory staircase of a Preisach model (see the module docs): fixed capacity, `Copy`.
#[derive(Debug, Clone, Copy)]
pub struct PreisachMemory {
    /// Entry `k`: a `Down(ops[k])` for even `k`, an `Up(ops[k])` for odd `k`.
    ops: [u8; CAPACITY],
    len: u8,
    levels: u8,
    started: bool,
}

impl PreisachMemory {
    /// An empty memory of `levels` levels (at most [`MAX_LEVELS`]); the first input starts it.
    pub fn new(levels: usize) -> Self {
        Self {
            ops: [0; CAPACITY],
            len: 1,
            levels: levels.min(MAX_LEVELS) as u8,
            started: false,
        }
    }

    /// Whether an input has been applied.
    pub fn started(&self) -> bool {
        self.started
    }

    /// The entries, oldest first (`Down(0)`, `Up(U₁)`, `Down(D₁)`, …).
    pub fn entries(&self) -> &[u8] {
        &self.ops[..self.len as usize]
    }

    /// Switches up the α-lines `i < u`.
    #[inline(always)]
    fn up(&mut self, u: u8) {
        if u == 0 {
            return;
        }
        let mut len = self.len as usize;
        if len.is_multiple_of(2) {
            // The top is an `Up`: the new one is covered by it, or covers it.
            if self.ops[len - 1] >= u {
                return;
            }
            len -= 1;
        }
        // The top is a `Down`: wipe out every (Up, Down) pair whose maximum `u` reaches.
        while len >= 3 && self.ops[len - 2] <= u {
            len -= 2;
        }
        self.ops[len] = u;
        self.len = (len + 1) as u8;
    }

    /// Switches down the β-columns `j ≥ d`.
    #[inline(always)]
    fn down(&mut self, d: u8) {
        if d >= self.levels {
            return;
        }
        let mut len = self.len as usize;
        if !len.is_multiple_of(2) {
            // The top is a `Down` (the bottom `Down(0)` covers every `d`).
            if self.ops[len - 1] <= d {
                return;
            }
            len -= 1;
        }
        // The top is an `Up`: wipe out every (Down, Up) pair whose minimum `d` reaches.
        while len >= 2 && self.ops[len - 2] >= d {
            len -= 2;
        }
        self.ops[len] = d;
        self.len = (len + 1) as u8;
    }

    /// The demagnetised memory around the first input at level `u` (module docs): the
    /// staircase `j < B̃(i) = ⌈2u − i − 1⌉` built corner by corner, α-lines from the top.
    fn demagnetise(&mut self, u: f64) {
        let n = self.levels as usize;
        let mut prev = 0u8;
        for i in (0..n).rev() {
            let b = (2.0 * u - i as f64 - 1.0).ceil().max(0.0).min(n as f64) as u8;
            if b > prev {
                self.up((i + 1) as u8);
                self.down(b);
                prev = b;
            }
        }
    }

    /// Applies the input `x` on `grid`.
    #[inline(always)]
    pub fn step(&mut self, grid: &PreisachGrid, x: f64) {
        self.step_switching(grid, x);
    }

    /// [`PreisachMemory::step`], which returns the input's `(U, D)` ([`PreisachGrid::switches`]).
    #[inline(always)]
    pub fn step_switching(&mut self, grid: &PreisachGrid, x: f64) -> (u8, u8) {
        if !self.started {
            self.started = true;
            self.demagnetise(grid.level(x));
        }
        let (u, d) = grid.switches(x);
        self.up(u);
        self.down(d);
        (u, d)
    }

    /// `B(i)` for every α-line into `out` (length N): relay `(i, j)` is up iff `j < out[i]`.
    pub fn boundary(&self, out: &mut [u8]) {
        out.fill(0);
        let len = self.len as usize;
        let mut k = 1;
        while k < len {
            let u = self.ops[k] as usize;
            let d = if k + 1 < len {
                self.ops[k + 1]
            } else {
                self.levels
            };
            let below = if k + 2 < len { self.ops[k + 2] } else { 0 } as usize;
            for (i, o) in out.iter_mut().enumerate().take(u).skip(below) {
                *o = d.min((i + 1) as u8);
            }
            k += 2;
        }
    }

    /// `Σ μ` over the relays that are up, from the Everett table `q` of [`everett_table`]:
    /// one term per stored maximum.
    #[inline(always)]
    pub fn up_sum(&self, q: &[f64]) -> f64 {
        let len = self.len as usize;
        let w = self.levels as usize + 1;
        let mut s = 0.0;
        let mut k = 1;
        while k < len {
            let u = self.ops[k] as usize;
            let d = if k + 1 < len {
                self.ops[k + 1] as usize
            } else {
                w - 1
            };
            let below = if k + 2 < len {
                self.ops[k + 2] as usize
            } else {
                0
            };
            s += q[u * w + d] - q[below * w + d];
            k += 2;
        }
        s
    }
}

/// The Everett table of relay weights `mu` (triangle order, [`PreisachGrid::cell`]):
/// `Q(U, D) = Σ μ_ij over i < U, j < min(D, i + 1)`, row-major `(N+1) × (N+1)`.
pub fn everett_table(levels: usize, mu: &[f64]) -> Vec<f64> {
    let w = levels + 1;
    let mut q = vec![0.0; w * w];
    for u in 1..w {
        let i = u - 1;
        let mut row = 0.0;
        for d in 0..w {
            if d >= 1 && d - 1 <= i {
                row += mu[PreisachGrid::cell(i, d - 1)];
            }
            q[u * w + d] = q[i * w + d] + row;
        }
    }
    q
}

/// A fitted Preisach model as a concrete, allocation-free predictor: `bias = offset + Σ μ_c·s_c`
/// over the relays (`s = ±1`), summed through the Everett table in O(entries of the memory) per
/// step. The bench `preisach` measures it.
#[derive(Debug, Clone)]
pub struct PreisachPredictor {
    grid: PreisachGrid,
    memory: PreisachMemory,
    q: Box<[f64]>,
    /// `offset − Σ μ`: the output with every relay down.
    base: f64,
}

impl PreisachPredictor {
    /// A predictor on `grid` with relay weights `mu` (N(N+1)/2, triangle order; 0 for a relay
    /// the model leaves out) and a constant `offset` (bias unit); `None` if the grid is invalid or
    /// `mu` has another length.
    pub fn new(grid: PreisachGrid, mu: &[f64], offset: f64) -> Option<Self> {
        (grid.is_valid() && mu.len() == grid.cells()).then(|| Self {
            grid,
            memory: PreisachMemory::new(grid.levels),
            q: everett_table(grid.levels, mu).into(),
            base: offset - mu.iter().sum::<f64>(),
        })
    }

    /// Applies the input `x` and returns the predicted bias there.
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        self.memory.step(&self.grid, x);
        self.base + 2.0 * self.memory.up_sum(&self.q)
    }

    /// The bias the input `x` would give, without changing the state.
    #[inline]
    pub fn peek(&self, x: f64) -> f64 {
        let mut m = self.memory;
        m.step(&self.grid, x);
        self.base + 2.0 * m.up_sum(&self.q)
    }

    /// The memory (its staircase of dominant extrema).
    pub fn memory(&self) -> &PreisachMemory {
        &self.memory
    }
}
