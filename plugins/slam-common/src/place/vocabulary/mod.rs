//! A hierarchical bag-of-words vocabulary over binary descriptors, as DBoW2 builds and uses
//! it for ORB-SLAM2: Gálvez-López and Tardós, "Bags of Binary Words for Fast Place
//! Recognition in Image Sequences", IEEE Transactions on Robotics 28(5), 2012. Implemented
//! from the paper; no DBoW2 code was used.
//!
//! Unlike [`crate::place::bow`], whose dictionary grows online, this vocabulary is trained once,
//! offline, on descriptors from training images, and is then fixed.
//!
//! # Training
//!
//! [`Vocabulary::train`] clusters the training descriptors into a tree of branching factor
//! `k` and depth `L` ([`TrainConfig`]) by hierarchical k-means: the root holds all of them;
//! a node is split by k-means into (at most) `k` children, each taking the descriptors of
//! its cluster, down to depth `L`. The leaves are the *words*.
//!
//! - Distances are Hamming distances, and the centre of a cluster is its per-bit median
//!   (bit set iff strictly more than half of the cluster's descriptors have it set; ties
//!   give 0), as the paper prescribes for binary descriptors.
//! - Seeds are chosen by k-means++ (Arthur and Vassilvitskii, "k-means++: The Advantages of
//!   Careful Seeding", SODA 2007): the first uniformly at random, every next one with
//!   probability proportional to `D(x)²`, the squared distance to the nearest seed so far.
//!   (DBoW2's own implementation weighs by `D(x)` rather than `D(x)²`; this one follows the
//!   paper.) Seeding stops early when every descriptor coincides with a seed.
//! - Lloyd iterations alternate assignment (nearest centre, ties to the lower index) and
//!   centre update until the assignment no longer changes or after
//!   [`TrainConfig::max_iterations`] assignments. The last step is always an assignment, so
//!   every training descriptor lies under the nearest child at every level — the path
//!   [`Vocabulary::transform`] takes. Clusters left empty are dropped.
//! - A node whose descriptors take at most `k` distinct values is not clustered: each
//!   distinct value becomes a child of its own, a leaf (DBoW2 does this for nodes with at
//!   most `k` descriptors; merging duplicates avoids words no descriptor can reach). A node
//!   holding a single distinct value is a leaf. So leaves may be shallower than `L`.
//!
//! Each word `i` gets the inverse document frequency `idf_i = ln(N / n_i)` as its weight,
//! where `N` is the number of training images (empty ones included) and `n_i` the number of
//! them with at least one descriptor that [`Vocabulary::word_of`] maps to word `i`. Every
//! word holds a training descriptor, so `n_i ≥ 1`.
//!
//! Training is deterministic for a given [`TrainConfig::seed`], whatever the number of
//! threads: the random numbers of node `n` come from stream `n` of a ChaCha8 generator
//! seeded with the seed, and all arithmetic of the clustering is on integers.
//!
//! # Node and word numbering
//!
//! Nodes are numbered breadth-first from the root (0), and the children of a node have
//! consecutive ids in the order of their clusters. Words are numbered from 0 in the order of
//! their nodes' ids.
//!
//! # Bag-of-words vector, direct index, score
//!
//! [`Vocabulary::transform`] maps every descriptor of an image to a word by descending the
//! tree, taking the nearest child (Hamming distance, ties to the lower id) at each node. The
//! [`BowVector`] is the tf-idf vector `v_i = (c_i / n) · idf_i` (`c_i` descriptors of the
//! `n` quantised to word `i`), L1-normalised; the `1/n` cancels in the normalisation. Words
//! of weight 0 (present in every training image) carry no information and are left out, as
//! in DBoW2. The [`FeatureVector`] is the paper's direct index: for every descriptor, its
//! index in the input is listed under the node of its path at depth `L − levels_up` (the
//! root if `levels_up ≥ L`; the word itself if the word is shallower) — the ancestor
//! `levels_up` levels above a word at full depth. Every descriptor is listed, including
//! those of zero-weight words (DBoW2 leaves them out; feature matching wants them).
//!
//! [`Vocabulary::score`] is the paper's L1 score
//! `s(v₁, v₂) = 1 − ½ ‖v₁/‖v₁‖₁ − v₂/‖v₂‖₁‖₁ ∈ [0, 1]`, computed over the common words only
//! as `½ Σ (|a_i| + |b_i| − |a_i − b_i|)` of the normalised vectors.
//!
//! # File format
//!
//! [`Vocabulary::write_to`] writes, all integers little-endian:
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `VINEVOC\0` |
//! | 4 | format version, `u32` = 1 |
//! | 4 | `k`, `u32` |
//! | 4 | `L` (levels), `u32` |
//! | 4 | number of nodes `M` (root included), `u32` |
//! | 4 | number of words `W`, `u32` |
//! | 8 | number of training images `N`, `u64` |
//! | 4·M | number of children of every node, by id, `u32` |
//! | 32·(M − 1) | descriptor of every node but the root, by id |
//! | 8·W | idf weight of every word, by id, IEEE-754 `f64` |
//! | 8 | FNV-1a 64-bit hash of all the preceding bytes, `u64` |
//!
//! The tree is implied by the breadth-first numbering: the children of node `i` are the
//! `c_i` nodes from `1 + Σ_{j<i} c_j` on, and the words are the non-root nodes without
//! children, in id order. A file is thus `12 + 36·M + 8·W` bytes: 23 MB for `k = 10`,
//! `L = 6` trained on 500k descriptors in the tests (547k nodes, 455k words; every word
//! holds a training descriptor, so `W` never exceeds their number).
//! [`Vocabulary::read_from`] checks the magic, version, hash, sizes and the tree's
//! consistency, and reports a bad file as a [`VocabularyError`] naming the problem.

use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::{fmt, fs};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

pub use crate::place::bow::Descriptor;

mod file;
mod train;

/// A word (leaf of the tree), numbered from 0 in node order.
pub type WordId = u32;
/// A node of the tree, numbered breadth-first from the root (0).
pub type NodeId = u32;

/// First bytes of a vocabulary file.
pub const MAGIC: [u8; 8] = *b"VINEVOC\0";
/// Version of the file format written by [`Vocabulary::write_to`].
pub const FORMAT_VERSION: u32 = 1;
/// Largest accepted branching factor.
pub const MAX_K: usize = 1 << 16;
/// Largest accepted depth.
pub const MAX_LEVELS: usize = 32;

/// Bytes before the per-node data in a file.
const HEADER_BYTES: usize = 36;
/// Below this many descriptors a k-means step is not split across threads.
const PARALLEL_MIN: usize = 1 << 13;
/// No node.
const NONE: u32 = u32::MAX;

/// Parameters of [`Vocabulary::train`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrainConfig {
    /// Branching factor: children per node, 2 to [`MAX_K`] (ORB-SLAM2: 10).
    pub k: usize,
    /// Depth of the tree: levels below the root, 1 to [`MAX_LEVELS`] (ORB-SLAM2: 6).
    pub levels: usize,
    /// Seed of the k-means++ seeding; the same seed gives the same vocabulary.
    pub seed: u64,
    /// Most assignment steps of a node's k-means, at least 1 (DBoW2 iterates to
    /// convergence, with no limit). The default 10 is a compromise measured on the
    /// simulated route of the tests: against 10, training on 200k descriptors takes 25 %
    /// less time with 5 steps and 40 % more with 25, while the margin by which neighbouring
    /// locations outscore far ones moves from 0.29 to 0.26 (5) or 0.30 (25).
    pub max_iterations: usize,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            k: 10,
            levels: 6,
            seed: 0,
            max_iterations: 10,
        }
    }
}

/// An image's bag of words: `(word, weight)` by increasing word, L1-normalised tf-idf.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BowVector {
    pub entries: Vec<(WordId, f64)>,
}

/// An image's direct index: `(node, indices of the descriptors under it)` by increasing
/// node, the indices increasing.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FeatureVector {
    pub entries: Vec<(NodeId, Vec<u32>)>,
}

/// Why a vocabulary could not be trained, read or written.
#[derive(Debug, thiserror::Error)]
pub enum VocabularyError {
    #[error("invalid training configuration: {0}")]
    InvalidConfig(String),
    #[error("no training descriptors")]
    NoDescriptors,
    #[error("the vocabulary would have more than 2³² − 1 nodes")]
    TooLarge,
    #[error("not a vocabulary file: magic {found:02x?}, expected {MAGIC:02x?}")]
    BadMagic { found: [u8; 8] },
    #[error("unsupported vocabulary file version {found} (this build reads {FORMAT_VERSION})")]
    UnsupportedVersion { found: u32 },
    #[error("vocabulary file truncated: ended in the {0}")]
    Truncated(&'static str),
    #[error(
        "vocabulary file corrupt: checksum {computed:#018x} of the content, {stored:#018x} stored"
    )]
    Checksum { stored: u64, computed: u64 },
    #[error("vocabulary file corrupt: {0}")]
    Corrupt(String),
    #[error("{}: {source}", path.display())]
    File {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("reading a vocabulary: {0}")]
    Io(#[from] io::Error),
}

/// A descriptor as four 64-bit words (little-endian byte order), aligned so that it never
/// straddles a cache line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(align(32))]
struct Bits([u64; 4]);

impl Bits {
    fn from_descriptor(d: &Descriptor) -> Self {
        let mut w = [0u64; 4];
        for (w, bytes) in w.iter_mut().zip(d.chunks_exact(8)) {
            *w = u64::from_le_bytes(bytes.try_into().expect("8 bytes"));
        }
        Self(w)
    }

    fn to_descriptor(self) -> Descriptor {
        let mut d = [0u8; 32];
        for (bytes, w) in d.chunks_exact_mut(8).zip(self.0) {
            bytes.copy_from_slice(&w.to_le_bytes());
        }
        d
    }

    /// Hamming distance, with the hardware popcount where the target has one.
    #[cfg(not(all(
        any(target_arch = "x86_64", target_arch = "x86"),
        not(target_feature = "popcnt")
    )))]
    #[inline]
    fn distance(&self, other: &Self) -> u32 {
        (self.0[0] ^ other.0[0]).count_ones()
            + (self.0[1] ^ other.0[1]).count_ones()
            + (self.0[2] ^ other.0[2]).count_ones()
            + (self.0[3] ^ other.0[3]).count_ones()
    }

    /// Hamming distance for x86 targets without the `popcnt` instruction (the baseline
    /// x86-64 target): an explicit SWAR popcount that shares its last steps between the
    /// four words, which also vectorises across children in [`nearest`], is about 25 %
    /// faster there than four software `count_ones`. Building with
    /// `-C target-feature=+popcnt` (or `target-cpu=x86-64-v2`) selects the version above,
    /// about twice as fast again.
    #[cfg(all(
        any(target_arch = "x86_64", target_arch = "x86"),
        not(target_feature = "popcnt")
    ))]
    #[inline]
    fn distance(&self, other: &Self) -> u32 {
        const M1: u64 = 0x5555_5555_5555_5555;
        const M2: u64 = 0x3333_3333_3333_3333;
        const M4: u64 = 0x0f0f_0f0f_0f0f_0f0f;
        const M8: u64 = 0x00ff_00ff_00ff_00ff;
        let x = [
            self.0[0] ^ other.0[0],
            self.0[1] ^ other.0[1],
            self.0[2] ^ other.0[2],
            self.0[3] ^ other.0[3],
        ];
        let x = x.map(|x| x - ((x >> 1) & M1));
        let x = x.map(|x| (x & M2) + ((x >> 2) & M2));
        let x = x.map(|x| (x + (x >> 4)) & M4);
        // Bytes of at most 8 each, summed: at most 32; then 16-bit lanes of at most 64,
        // whose sum (at most 256) the multiplication gathers in the top lane.
        let bytes = x[0] + x[1] + x[2] + x[3];
        let lanes = (bytes & M8) + ((bytes >> 8) & M8);
        (lanes.wrapping_mul(0x0001_0001_0001_0001) >> 48) as u32
    }
}

/// Index of the centre nearest to `q`, ties to the lower index. Distances are computed 16
/// centres at a time before the comparisons, which lets the compiler vectorise them.
#[inline]
fn nearest(centres: &[Bits], q: &Bits) -> usize {
    let mut best = 0;
    let mut best_distance = u32::MAX;
    for (chunk_index, chunk) in centres.chunks(16).enumerate() {
        let mut distances = [u32::MAX; 16];
        for (d, c) in distances.iter_mut().zip(chunk) {
            *d = c.distance(q);
        }
        for (i, &d) in distances[..chunk.len()].iter().enumerate() {
            if d < best_distance {
                best_distance = d;
                best = chunk_index * 16 + i;
            }
        }
    }
    best
}

/// A trained hierarchical vocabulary (module documentation).
#[derive(Clone, PartialEq)]
pub struct Vocabulary {
    k: usize,
    levels: usize,
    training_images: u64,
    /// Descriptor of every node, by id (the root's is zero and unused).
    centres: Vec<Bits>,
    /// The children of node `i` are the ids `first_child[i]..first_child[i + 1]`; one entry
    /// more than there are nodes.
    first_child: Vec<NodeId>,
    /// Parent of every node (`NONE` for the root).
    parents: Vec<NodeId>,
    /// Depth of every node (the root's is 0).
    depths: Vec<u8>,
    /// Word of every node (`NONE` for inner nodes and the root).
    node_words: Vec<WordId>,
    /// Node of every word.
    word_nodes: Vec<NodeId>,
    /// idf weight of every word.
    weights: Vec<f64>,
}

impl fmt::Debug for Vocabulary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Vocabulary")
            .field("k", &self.k)
            .field("levels", &self.levels)
            .field("training_images", &self.training_images)
            .field("nodes", &self.node_count())
            .field("words", &self.word_count())
            .finish_non_exhaustive()
    }
}

impl Vocabulary {
    /// Branching factor.
    pub fn k(&self) -> usize {
        self.k
    }

    /// Depth `L` of the tree (leaves may be shallower).
    pub fn levels(&self) -> usize {
        self.levels
    }

    /// Number of words (leaves).
    pub fn word_count(&self) -> usize {
        self.word_nodes.len()
    }

    /// Number of nodes, the root and the words included.
    pub fn node_count(&self) -> usize {
        self.centres.len()
    }

    /// Number `N` of training images, for the idf weights.
    pub fn training_images(&self) -> u64 {
        self.training_images
    }

    /// The children of a node (empty for words).
    ///
    /// # Panics
    /// If the node does not exist, as do the other accessors taking a node or word id.
    pub fn children(&self, node: NodeId) -> Range<NodeId> {
        self.first_child[node as usize]..self.first_child[node as usize + 1]
    }

    /// The parent of a node; `None` for the root.
    pub fn parent(&self, node: NodeId) -> Option<NodeId> {
        Some(self.parents[node as usize]).filter(|&p| p != NONE)
    }

    /// Depth of a node: 0 for the root, at most [`Vocabulary::levels`].
    pub fn depth(&self, node: NodeId) -> usize {
        self.depths[node as usize] as usize
    }

    /// A node's descriptor (the cluster centre); all zeros for the root.
    pub fn node_descriptor(&self, node: NodeId) -> Descriptor {
        self.centres[node as usize].to_descriptor()
    }

    /// The word a node is, if it is a leaf.
    pub fn node_word(&self, node: NodeId) -> Option<WordId> {
        Some(self.node_words[node as usize]).filter(|&w| w != NONE)
    }

    /// The leaf node of a word.
    pub fn word_node(&self, word: WordId) -> NodeId {
        self.word_nodes[word as usize]
    }

    /// A word's idf weight `ln(N / n_i)`.
    pub fn word_weight(&self, word: WordId) -> f64 {
        self.weights[word as usize]
    }

    /// Descends from the root to a word, taking the nearest child at each node; returns the
    /// word's node and the node of the path at depth `target` (the word's node if the word
    /// is shallower).
    #[inline]
    fn descend(&self, q: &Bits, target: usize) -> (NodeId, NodeId) {
        let mut node = 0usize;
        let mut at_target = 0usize;
        let mut depth = 0;
        loop {
            let (start, end) = (
                self.first_child[node] as usize,
                self.first_child[node + 1] as usize,
            );
            if start == end {
                break;
            }
            node = start + nearest(&self.centres[start..end], q);
            depth += 1;
            if depth <= target {
                at_target = node;
            }
        }
        (node as NodeId, at_target as NodeId)
    }

    /// The word of a descriptor and its idf weight.
    pub fn word_of(&self, d: &Descriptor) -> (WordId, f64) {
        let (leaf, _) = self.descend(&Bits::from_descriptor(d), 0);
        let w = self.node_words[leaf as usize];
        (w, self.weights[w as usize])
    }

    /// An image's bag-of-words vector and direct index, with every descriptor listed under
    /// the node of its path at depth `L − levels_up` (module documentation; ORB-SLAM2 uses
    /// `levels_up = 4`).
    ///
    /// # Panics
    /// With 2³² descriptors or more.
    pub fn transform(
        &self,
        descriptors: &[Descriptor],
        levels_up: usize,
    ) -> (BowVector, FeatureVector) {
        assert!(
            u32::try_from(descriptors.len()).is_ok(),
            "fewer than 2³² descriptors"
        );
        let target = self.levels.saturating_sub(levels_up);
        let mut words: Vec<(WordId, f64)> = Vec::with_capacity(descriptors.len());
        let mut nodes: Vec<(NodeId, u32)> = Vec::with_capacity(descriptors.len());
        for (i, d) in descriptors.iter().enumerate() {
            let (leaf, node) = self.descend(&Bits::from_descriptor(d), target);
            let w = self.node_words[leaf as usize];
            let weight = self.weights[w as usize];
            if weight > 0.0 {
                words.push((w, weight));
            }
            nodes.push((node, i as u32));
        }

        words.sort_unstable_by_key(|&(w, _)| w);
        let mut bow = BowVector {
            entries: Vec::with_capacity(words.len()),
        };
        for (w, weight) in words {
            match bow.entries.last_mut() {
                Some((last, sum)) if *last == w => *sum += weight,
                _ => bow.entries.push((w, weight)),
            }
        }
        let norm: f64 = bow.entries.iter().map(|&(_, v)| v).sum();
        if norm > 0.0 {
            for (_, v) in &mut bow.entries {
                *v /= norm;
            }
        }

        nodes.sort_unstable();
        let mut features = FeatureVector::default();
        for (node, i) in nodes {
            match features.entries.last_mut() {
                Some((last, list)) if *last == node => list.push(i),
                _ => features.entries.push((node, vec![i])),
            }
        }
        (bow, features)
    }

    /// The L1 score `1 − ½ ‖a/‖a‖₁ − b/‖b‖₁‖₁` in [0, 1] (module documentation): 1 for
    /// proportional vectors, 0 for vectors without common words or when either is empty
    /// or zero. Both vectors must be sorted by word.
    pub fn score(a: &BowVector, b: &BowVector) -> f64 {
        let norm = |v: &BowVector| v.entries.iter().map(|&(_, x)| x.abs()).sum::<f64>();
        let (na, nb) = (norm(a), norm(b));
        if na <= 0.0 || nb <= 0.0 || !na.is_finite() || !nb.is_finite() {
            return 0.0;
        }
        let (mut i, mut j) = (0, 0);
        let mut sum = 0.0;
        while i < a.entries.len() && j < b.entries.len() {
            let ((wa, va), (wb, vb)) = (a.entries[i], b.entries[j]);
            if wa < wb {
                i += 1;
            } else if wb < wa {
                j += 1;
            } else {
                let (x, y) = (va / na, vb / nb);
                sum += x.abs() + y.abs() - (x - y).abs();
                i += 1;
                j += 1;
            }
        }
        (0.5 * sum).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_is_the_popcount_of_the_xor() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let ones = Bits([u64::MAX; 4]);
        let zero = Bits::default();
        assert_eq!(ones.distance(&zero), 256);
        assert_eq!(zero.distance(&ones), 256);
        assert_eq!(ones.distance(&ones), 0);
        for _ in 0..10_000 {
            let a = Bits(rng.random());
            // Sparse and dense differences as well as random ones.
            let b = match rng.random_range(0..3) {
                0 => Bits(rng.random()),
                1 => Bits(a.0.map(|w| w ^ (1 << rng.random_range(0..64)))),
                _ => Bits(a.0.map(|w| !w ^ (1 << rng.random_range(0..64)))),
            };
            let expected: u32 = a.0.iter().zip(b.0).map(|(x, y)| (x ^ y).count_ones()).sum();
            assert_eq!(a.distance(&b), expected);
        }
    }

    #[test]
    fn nearest_takes_the_lowest_index_among_ties_across_chunks() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for n in [1, 2, 10, 16, 17, 40] {
            for _ in 0..200 {
                let centres: Vec<Bits> = (0..n).map(|_| Bits(rng.random())).collect();
                let mut q = centres[rng.random_range(0..n)];
                q.0[0] ^= rng.random::<u64>() & rng.random::<u64>();
                let expected = (0..n)
                    .min_by_key(|&i| (centres[i].distance(&q), i))
                    .expect("centres");
                assert_eq!(nearest(&centres, &q), expected);
            }
        }
        let same = vec![Bits([7; 4]); 20];
        assert_eq!(nearest(&same, &Bits([7; 4])), 0);
    }
}
