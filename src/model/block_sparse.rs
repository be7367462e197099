//! `[C1 | C2]` stored per proxy (paper §4.3, Eq. 5–6): the layout both the CPU palette and the
//! GPU's block-sparse product read.

use super::Model;

/// `[C1 | C2]: (4P x (3P + 4J))` stored per proxy: proxy e's 4 rows (4e .. 4e + 3) keep only
/// the columns where one of them is non-zero, each as its column index k and the vec4 of the 4
/// rows' values (T_e's columns 0..4). A column below 3P is column k % 3 of key k / 3, above it
/// column k' % 4 of bone k' / 4 (k' = k − 3P). A joint-blend proxy touches its own key's 3
/// columns and its 2-3 bones' 4 each (~11 of 3P + 4J); the paper's reduction and synthetic
/// models are dense.
/// The block-sparse layout is chosen when the stored columns are fewer than this fraction of
/// the P (3P + 4J) of the dense matrix (then it is also the smaller: 20 bytes a stored column
/// against 16 a dense one).
pub(crate) const MAX_SPARSE_DENSITY: f64 = 0.25;

#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct BlockSparse {
    /// P + 1: proxy e's columns are `columns[offsets[e]..offsets[e + 1]]`.
    pub offsets: Vec<u32>,
    pub columns: Vec<u32>,
    pub values: Vec<[f32; 4]>,
}

impl BlockSparse {
    /// `model`'s `[C1 | C2]` with its zero columns left out, proxy by proxy.
    pub fn of(model: &Model) -> BlockSparse {
        let (p, j) = (model.proxy_count(), model.bone_count());
        let (width, a) = (3 * p + 4 * j, model.c1_c2());
        let mut blocks = BlockSparse {
            offsets: Vec::with_capacity(p + 1),
            ..BlockSparse::default()
        };
        blocks.offsets.push(0);
        for e in 0..p {
            for k in 0..width {
                let column = [0, 1, 2, 3].map(|r| a[(4 * e + r) * width + k]);
                if column.iter().any(|&x| x != 0.0) {
                    blocks.columns.push(k as u32);
                    blocks.values.push(column);
                }
            }
            blocks.offsets.push(blocks.columns.len() as u32);
        }
        blocks
    }

    /// The layout the GPU's product runs on: `model`'s blocks, or `None` where the product
    /// stays the dense GEMM (no proxies, an all-zero matrix, or stored columns at or above
    /// [`MAX_SPARSE_DENSITY`] of the dense P (3P + 4J)).
    pub fn layout_of(model: &Model) -> Option<BlockSparse> {
        let blocks = BlockSparse::of(model);
        blocks.is_layout_of(model).then_some(blocks)
    }

    /// Whether these blocks (`model`'s) are the layout its product runs on
    /// ([`BlockSparse::layout_of`]).
    pub fn is_layout_of(&self, model: &Model) -> bool {
        let width = 3 * model.proxy_count() + 4 * model.bone_count();
        let stored = self.columns.len() as f64;
        let dense = (model.proxy_count() * width) as f64;
        stored > 0.0 && stored < MAX_SPARSE_DENSITY * dense
    }

    /// Proxy e's stored columns and their values.
    pub fn of_proxy(&self, e: usize) -> (&[u32], &[[f32; 4]]) {
        let range = self.offsets[e] as usize..self.offsets[e + 1] as usize;
        (&self.columns[range.clone()], &self.values[range])
    }

    /// Whether each proxy's stored columns below 3P (its key columns) are those of one key:
    /// then its invocation of the fused product evaluates that key's D_ℓ(q) and nothing else
    /// (glsl/fused_product.comp). True of joint-blend proxies (key e, its parent bone).
    pub fn one_key_per_proxy(&self) -> bool {
        let keys = 3 * (self.offsets.len().saturating_sub(1)) as u32;
        self.offsets.windows(2).all(|w| {
            let stored = self.columns.get(w[0] as usize..w[1] as usize);
            let mut key_columns = (stored.unwrap_or_default().iter())
                .filter(|&&k| k < keys)
                .map(|k| k / 3);
            key_columns
                .next()
                .is_none_or(|first| key_columns.all(|k| k == first))
        })
    }
}
