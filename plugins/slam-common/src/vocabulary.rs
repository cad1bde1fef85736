//! A hierarchical bag-of-words vocabulary over binary descriptors, as DBoW2 builds and uses
//! it for ORB-SLAM2: Gálvez-López and Tardós, "Bags of Binary Words for Fast Place
//! Recognition in Image Sequences", IEEE Transactions on Robotics 28(5), 2012. Implemented
//! from the paper; no DBoW2 code was used.
//!
//! Unlike [`crate::bow`], whose dictionary grows online, this vocabulary is trained once,
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

pub use crate::bow::Descriptor;

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

/// `SPREAD[b]` has byte `j` equal to bit `j` of `b`: adding it to a `u64` counts the bits of
/// a descriptor byte in eight byte-wide counters at once.
const SPREAD: [u64; 256] = {
    let mut table = [0u64; 256];
    let mut b = 0;
    while b < 256 {
        let mut j = 0;
        while j < 8 {
            if b >> j & 1 == 1 {
                table[b] |= 1 << (8 * j);
            }
            j += 1;
        }
        b += 1;
    }
    table
};

/// Per-cluster bit counts: `counts[c][i]` descriptors of cluster `c` have bit `i` set (bit
/// `i` is bit `i % 8` of byte `i / 8`), and `sizes[c]` descriptors are in cluster `c`.
#[derive(Clone)]
struct BitCounts {
    counts: Vec<[u32; 256]>,
    sizes: Vec<u32>,
}

impl BitCounts {
    fn new(clusters: usize) -> Self {
        Self {
            counts: vec![[0; 256]; clusters],
            sizes: vec![0; clusters],
        }
    }

    /// Counts of `points` labelled `labels`: byte-wide counters flushed every 255 additions.
    fn of(points: &[Bits], labels: &[u32], clusters: usize) -> Self {
        let mut out = Self::new(clusters);
        let mut packed = vec![[0u64; 32]; clusters];
        let mut pending = vec![0u8; clusters];
        let flush = |out: &mut Self, packed: &mut [u64; 32], c: usize| {
            for (byte, acc) in packed.iter_mut().enumerate() {
                for j in 0..8 {
                    out.counts[c][byte * 8 + j] += (*acc >> (8 * j) & 0xff) as u32;
                }
                *acc = 0;
            }
        };
        for (p, &l) in points.iter().zip(labels) {
            let c = l as usize;
            let acc = &mut packed[c];
            for (w, word) in p.0.iter().enumerate() {
                for (b, byte) in word.to_le_bytes().into_iter().enumerate() {
                    acc[w * 8 + b] += SPREAD[byte as usize];
                }
            }
            out.sizes[c] += 1;
            pending[c] += 1;
            if pending[c] == u8::MAX {
                flush(&mut out, acc, c);
                pending[c] = 0;
            }
        }
        for (c, acc) in packed.iter_mut().enumerate() {
            if pending[c] > 0 {
                flush(&mut out, acc, c);
            }
        }
        out
    }

    fn add(mut self, other: Self) -> Self {
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            for (x, y) in a.iter_mut().zip(b) {
                *x += y;
            }
        }
        for (a, b) in self.sizes.iter_mut().zip(&other.sizes) {
            *a += b;
        }
        self
    }

    /// The per-bit median of cluster `c` (bit set iff set in more than half), or `None` if
    /// the cluster is empty.
    fn median(&self, c: usize) -> Option<Bits> {
        let n = self.sizes[c];
        (n > 0).then(|| {
            let mut d = [0u8; 32];
            for (i, &count) in self.counts[c].iter().enumerate() {
                if 2 * u64::from(count) > u64::from(n) {
                    d[i / 8] |= 1 << (i % 8);
                }
            }
            Bits::from_descriptor(&d)
        })
    }
}

/// Nearest-centre labels of `points`, split across threads for large sets.
fn assign(points: &[Bits], centres: &[Bits]) -> Vec<u32> {
    let mut labels = vec![0u32; points.len()];
    let label = |(l, p): (&mut u32, &Bits)| *l = nearest(centres, p) as u32;
    if points.len() >= PARALLEL_MIN {
        labels
            .par_iter_mut()
            .zip(points.par_iter())
            .with_min_len(PARALLEL_MIN / 2)
            .for_each(label);
    } else {
        labels.iter_mut().zip(points).for_each(label);
    }
    labels
}

/// Bit counts of labelled points, split across threads for large sets (integer sums, so
/// the result does not depend on the split).
fn bit_counts(points: &[Bits], labels: &[u32], clusters: usize) -> BitCounts {
    if points.len() >= PARALLEL_MIN {
        points
            .par_chunks(PARALLEL_MIN / 2)
            .zip(labels.par_chunks(PARALLEL_MIN / 2))
            .map(|(p, l)| BitCounts::of(p, l, clusters))
            .reduce(|| BitCounts::new(clusters), BitCounts::add)
    } else {
        BitCounts::of(points, labels, clusters)
    }
}

/// Lowers every `d2[i]` to the squared distance from `points[i]` to `centre` if nearer.
fn lower_distances(points: &[Bits], d2: &mut [u64], centre: &Bits) {
    let lower = |(d, p): (&mut u64, &Bits)| *d = (*d).min(u64::from(p.distance(centre)).pow(2));
    if points.len() >= PARALLEL_MIN {
        d2.par_iter_mut()
            .zip(points.par_iter())
            .with_min_len(PARALLEL_MIN / 2)
            .for_each(lower);
    } else {
        d2.iter_mut().zip(points).for_each(lower);
    }
}

/// k-means++ seeds (module documentation): at most `k`, distinct.
fn seeds(points: &[Bits], k: usize, rng: &mut ChaCha8Rng) -> Vec<Bits> {
    let mut centres = vec![points[rng.random_range(0..points.len())]];
    let mut d2 = vec![u64::MAX; points.len()];
    lower_distances(points, &mut d2, &centres[0]);
    while centres.len() < k {
        let total: u64 = d2.iter().sum();
        if total == 0 {
            break;
        }
        let target = rng.random_range(0..total);
        let mut cumulative = 0;
        let chosen = d2
            .iter()
            .position(|&w| {
                cumulative += w;
                cumulative > target
            })
            .expect("target below the total");
        centres.push(points[chosen]);
        lower_distances(points, &mut d2, &points[chosen]);
    }
    centres
}

/// A child made by splitting a node: its descriptor and the training descriptors under it
/// (empty when the child is known to be a leaf).
struct Child {
    centre: Bits,
    members: Vec<Bits>,
}

/// The distinct values of `points` in order of first occurrence, if there are at most `k`.
fn few_distinct(points: &[Bits], k: usize) -> Option<Vec<Bits>> {
    let mut distinct: Vec<Bits> = Vec::with_capacity(k + 1);
    for p in points {
        if !distinct.contains(p) {
            if distinct.len() == k {
                return None;
            }
            distinct.push(*p);
        }
    }
    Some(distinct)
}

/// Splits a node's descriptors into its children (module documentation).
fn split(points: Vec<Bits>, config: &TrainConfig, node: NodeId) -> Vec<Child> {
    if let Some(distinct) = few_distinct(&points, config.k) {
        return distinct
            .into_iter()
            .map(|centre| Child {
                centre,
                members: Vec::new(),
            })
            .collect();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    rng.set_stream(u64::from(node));
    let mut centres = seeds(&points, config.k, &mut rng);
    let mut labels: Vec<u32> = Vec::new();
    for iteration in 0..config.max_iterations {
        let new = assign(&points, &centres);
        let converged = new == labels;
        labels = new;
        if converged || iteration + 1 == config.max_iterations {
            break;
        }
        let counts = bit_counts(&points, &labels, centres.len());
        for (c, centre) in centres.iter_mut().enumerate() {
            if let Some(median) = counts.median(c) {
                *centre = median;
            }
        }
    }
    let mut members: Vec<Vec<Bits>> = vec![Vec::new(); centres.len()];
    for (p, &l) in points.iter().zip(&labels) {
        members[l as usize].push(*p);
    }
    drop(points);
    centres
        .into_iter()
        .zip(members)
        .filter(|(_, m)| !m.is_empty())
        .map(|(centre, members)| Child { centre, members })
        .collect()
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
    /// Trains a vocabulary on the descriptors of training images (module documentation);
    /// `images` holds each training image's descriptors, for the idf weights.
    ///
    /// Fails on an invalid configuration, when there is no descriptor at all, or when the
    /// tree would exceed 2³² − 1 nodes.
    pub fn train(
        images: &[Vec<Descriptor>],
        config: &TrainConfig,
    ) -> Result<Self, VocabularyError> {
        if !(2..=MAX_K).contains(&config.k) {
            return Err(VocabularyError::InvalidConfig(format!(
                "k must be in 2..={MAX_K}, got {}",
                config.k
            )));
        }
        if !(1..=MAX_LEVELS).contains(&config.levels) {
            return Err(VocabularyError::InvalidConfig(format!(
                "levels must be in 1..={MAX_LEVELS}, got {}",
                config.levels
            )));
        }
        if config.max_iterations == 0 {
            return Err(VocabularyError::InvalidConfig(
                "max_iterations must be at least 1".into(),
            ));
        }
        let all: Vec<Bits> = images.iter().flatten().map(Bits::from_descriptor).collect();
        if all.is_empty() {
            return Err(VocabularyError::NoDescriptors);
        }
        if u32::try_from(all.len()).is_err() {
            return Err(VocabularyError::InvalidConfig(
                "at most 2³² − 1 training descriptors".into(),
            ));
        }

        // Breadth-first, one level at a time: the nodes of a level are split in parallel,
        // then their children numbered in order.
        let mut centres = vec![Bits::default()];
        let mut child_counts: Vec<u32> = vec![0];
        let mut level: Vec<(NodeId, Vec<Bits>)> = vec![(0, all)];
        let mut depth = 0;
        while !level.is_empty() {
            let ids: Vec<NodeId> = level.iter().map(|&(id, _)| id).collect();
            let splits: Vec<Vec<Child>> = level
                .into_par_iter()
                .map(|(id, points)| split(points, config, id))
                .collect();
            depth += 1;
            let mut next = Vec::new();
            for (parent, children) in ids.into_iter().zip(splits) {
                child_counts[parent as usize] = children.len() as u32;
                for child in children {
                    let id = NodeId::try_from(centres.len())
                        .ok()
                        .filter(|&id| id != NONE)
                        .ok_or(VocabularyError::TooLarge)?;
                    centres.push(child.centre);
                    child_counts.push(0);
                    let spread = child.members.iter().any(|m| *m != child.members[0]);
                    if depth < config.levels && spread {
                        next.push((id, child.members));
                    }
                }
            }
            level = next;
        }

        let mut vocabulary = Self::from_tree(
            config.k,
            config.levels,
            images.len() as u64,
            centres,
            &child_counts,
        );

        // n_i: the training images holding word i.
        let words_per_image: Vec<Vec<WordId>> = images
            .par_iter()
            .map(|image| {
                let mut words: Vec<WordId> =
                    image.iter().map(|d| vocabulary.word_of(d).0).collect();
                words.sort_unstable();
                words.dedup();
                words
            })
            .collect();
        let mut holders = vec![0u64; vocabulary.word_count()];
        for &w in words_per_image.iter().flatten() {
            holders[w as usize] += 1;
        }
        let n = images.len() as f64;
        vocabulary.weights = holders
            .into_iter()
            .map(|h| if h == 0 { 0.0 } else { (n / h as f64).ln() })
            .collect();
        Ok(vocabulary)
    }

    /// The vocabulary of a breadth-first tree given by its nodes' descriptors and numbers of
    /// children (checked by the caller), with zero weights.
    fn from_tree(
        k: usize,
        levels: usize,
        training_images: u64,
        centres: Vec<Bits>,
        child_counts: &[u32],
    ) -> Self {
        let nodes = centres.len();
        let mut first_child = Vec::with_capacity(nodes + 1);
        let mut parents = vec![NONE; nodes];
        let mut depths = vec![0u8; nodes];
        let mut next = 1u32;
        for (i, &c) in child_counts.iter().enumerate() {
            first_child.push(next);
            for child in next..next + c {
                parents[child as usize] = i as NodeId;
                depths[child as usize] = depths[i] + 1;
            }
            next += c;
        }
        first_child.push(next);
        let mut node_words = vec![NONE; nodes];
        let mut word_nodes = Vec::new();
        for (i, &c) in child_counts.iter().enumerate().skip(1) {
            if c == 0 {
                node_words[i] = word_nodes.len() as WordId;
                word_nodes.push(i as NodeId);
            }
        }
        let weights = vec![0.0; word_nodes.len()];
        Self {
            k,
            levels,
            training_images,
            centres,
            first_child,
            parents,
            depths,
            node_words,
            word_nodes,
            weights,
        }
    }

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

    /// Writes the vocabulary in the documented format (module documentation).
    pub fn write_to(&self, w: &mut impl Write) -> io::Result<()> {
        let nodes = self.node_count();
        let mut out = Vec::with_capacity(HEADER_BYTES + 36 * nodes + 8 * self.word_count() + 8);
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(self.k as u32).to_le_bytes());
        out.extend_from_slice(&(self.levels as u32).to_le_bytes());
        out.extend_from_slice(&(nodes as u32).to_le_bytes());
        out.extend_from_slice(&(self.word_count() as u32).to_le_bytes());
        out.extend_from_slice(&self.training_images.to_le_bytes());
        for pair in self.first_child.windows(2) {
            out.extend_from_slice(&(pair[1] - pair[0]).to_le_bytes());
        }
        for c in &self.centres[1..] {
            out.extend_from_slice(&c.to_descriptor());
        }
        for weight in &self.weights {
            out.extend_from_slice(&weight.to_bits().to_le_bytes());
        }
        let hash = fnv1a(&out);
        out.extend_from_slice(&hash.to_le_bytes());
        w.write_all(&out)
    }

    /// Writes the vocabulary in DBoW2's text format, the one ORB-SLAM2/3 read their
    /// `ORBvoc.txt` from (DBoW2 `TemplatedVocabulary::loadFromTextFile`, Gálvez-López and
    /// Tardós, "Bags of Binary Words for Fast Place Recognition in Image Sequences", IEEE
    /// T-RO 28(5), 2012): a line `k L scoring weighting` (here L1-norm scoring, 0, and
    /// TF-IDF weighting, 0, as ORB-SLAM's), then one line per node but the root,
    /// `parent is_leaf d0 … d31 weight`, with the descriptor's 32 bytes in decimal and the
    /// word's idf weight (0 for inner nodes). The reader numbers nodes in file order from 1
    /// (the root is 0), so nodes are written breadth first, each parent before its
    /// children, under those numbers.
    pub fn write_dbow2_text(&self, w: &mut impl Write) -> io::Result<()> {
        let mut out = BufWriter::new(w);
        writeln!(out, "{} {} 0 0", self.k, self.levels)?;
        let mut number = vec![0u32; self.node_count()];
        let mut queue = std::collections::VecDeque::from([0 as NodeId]);
        let mut next = 1u32;
        while let Some(node) = queue.pop_front() {
            for child in self.children(node) {
                number[child as usize] = next;
                next += 1;
                let word = self.node_word(child);
                write!(
                    out,
                    "{} {}",
                    number[node as usize],
                    u8::from(word.is_some())
                )?;
                for byte in self.node_descriptor(child) {
                    write!(out, " {byte}")?;
                }
                writeln!(out, " {}", word.map_or(0.0, |w| self.word_weight(w)))?;
                queue.push_back(child);
            }
        }
        out.flush()
    }

    /// Reads a vocabulary written by [`Vocabulary::write_to`], checking it (module
    /// documentation). Reads exactly the vocabulary's bytes from `r`.
    pub fn read_from(r: &mut impl Read) -> Result<Self, VocabularyError> {
        let mut header = [0u8; HEADER_BYTES];
        read_exact(r, &mut header, "header")?;
        let u32_at = |at: usize| u32::from_le_bytes(header[at..at + 4].try_into().expect("4"));
        let found: [u8; 8] = header[..8].try_into().expect("8 bytes");
        if found != MAGIC {
            return Err(VocabularyError::BadMagic { found });
        }
        let version = u32_at(8);
        if version != FORMAT_VERSION {
            return Err(VocabularyError::UnsupportedVersion { found: version });
        }
        let (k, levels, nodes, words) = (
            u32_at(12) as usize,
            u32_at(16) as usize,
            u32_at(20) as usize,
            u32_at(24) as usize,
        );
        let training_images = u64::from_le_bytes(header[28..36].try_into().expect("8 bytes"));
        let corrupt = |what: String| Err(VocabularyError::Corrupt(what));
        if !(2..=MAX_K).contains(&k) {
            return corrupt(format!("k = {k}, not in 2..={MAX_K}"));
        }
        if !(1..=MAX_LEVELS).contains(&levels) {
            return corrupt(format!("levels = {levels}, not in 1..={MAX_LEVELS}"));
        }
        if nodes < 2 || nodes == NONE as usize {
            return corrupt(format!("{nodes} nodes"));
        }
        if words == 0 || words >= nodes {
            return corrupt(format!("{words} words for {nodes} nodes"));
        }
        if training_images == 0 {
            return corrupt("no training images".into());
        }

        // Read the body in growing chunks, so that a corrupt count cannot allocate more than
        // the file holds.
        let body_len = 4 * nodes + 32 * (nodes - 1) + 8 * words;
        let mut body = Vec::new();
        let read = r.take(body_len as u64).read_to_end(&mut body)?;
        if read < body_len {
            let section = if read < 4 * nodes {
                "children counts"
            } else if read < 4 * nodes + 32 * (nodes - 1) {
                "node descriptors"
            } else {
                "word weights"
            };
            return Err(VocabularyError::Truncated(section));
        }
        let mut stored = [0u8; 8];
        read_exact(r, &mut stored, "checksum")?;
        let stored = u64::from_le_bytes(stored);
        let computed = fnv1a_continue(fnv1a(&header), &body);
        if stored != computed {
            return Err(VocabularyError::Checksum { stored, computed });
        }

        let (counts, rest) = body.split_at(4 * nodes);
        let (descriptors, weights) = rest.split_at(32 * (nodes - 1));
        let child_counts: Vec<u32> = counts
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
            .collect();
        // Children ranges are consecutive from 1; each must lie after its parent, so that
        // every node but the root has exactly one parent, with a smaller id.
        let mut next = 1u64;
        let mut depths = vec![0usize; nodes];
        for (i, &c) in child_counts.iter().enumerate() {
            if c as usize > k {
                return corrupt(format!("node {i} has {c} children, more than k = {k}"));
            }
            if c > 0 && next <= i as u64 {
                return corrupt(format!("node {i}'s children precede it"));
            }
            if next + u64::from(c) > nodes as u64 {
                return corrupt(format!("node {i}'s children exceed the {nodes} nodes"));
            }
            for child in next..next + u64::from(c) {
                depths[child as usize] = depths[i] + 1;
                if depths[child as usize] > levels {
                    return corrupt(format!("node {child} is deeper than {levels} levels"));
                }
            }
            next += u64::from(c);
        }
        if next != nodes as u64 {
            return corrupt(format!(
                "{} of the {nodes} nodes have no parent",
                nodes as u64 - next
            ));
        }
        if child_counts[0] == 0 {
            return corrupt("the root has no children".into());
        }
        let leaves = child_counts[1..].iter().filter(|&&c| c == 0).count();
        if leaves != words {
            return corrupt(format!("{leaves} leaves, but {words} words"));
        }

        let mut centres = Vec::with_capacity(nodes);
        centres.push(Bits::default());
        centres.extend(
            descriptors
                .chunks_exact(32)
                .map(|d| Bits::from_descriptor(d.try_into().expect("32 bytes"))),
        );
        let weights: Vec<f64> = weights
            .chunks_exact(8)
            .map(|b| f64::from_bits(u64::from_le_bytes(b.try_into().expect("8 bytes"))))
            .collect();
        if let Some(w) = weights.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
            return corrupt(format!("word {w} has weight {}", weights[w]));
        }
        let mut vocabulary = Self::from_tree(k, levels, training_images, centres, &child_counts);
        vocabulary.weights = weights;
        Ok(vocabulary)
    }

    /// Writes the vocabulary to a file, atomically: to a temporary file in the same
    /// directory, then renamed over `path`.
    pub fn save(&self, path: &Path) -> Result<(), VocabularyError> {
        let file_error = |path: &Path| {
            let path = path.to_path_buf();
            move |source| VocabularyError::File { path, source }
        };
        let name = path.file_name().ok_or_else(|| VocabularyError::File {
            path: path.to_path_buf(),
            source: io::Error::new(io::ErrorKind::InvalidInput, "not a file name"),
        })?;
        let mut temporary_name = std::ffi::OsString::from(".");
        temporary_name.push(name);
        temporary_name.push(format!(".{}.tmp", std::process::id()));
        let temporary = path.with_file_name(temporary_name);
        let written = (|| {
            let mut file = BufWriter::new(File::create(&temporary)?);
            self.write_to(&mut file)?;
            file.into_inner().map_err(|e| e.into_error())?.sync_all()
        })();
        if let Err(source) = written {
            let _ = fs::remove_file(&temporary);
            return Err(file_error(&temporary)(source));
        }
        fs::rename(&temporary, path).map_err(|source| {
            let _ = fs::remove_file(&temporary);
            file_error(path)(source)
        })
    }

    /// Reads a vocabulary file written by [`Vocabulary::save`]; trailing bytes are an error.
    pub fn load(path: &Path) -> Result<Self, VocabularyError> {
        let file_error = |source| VocabularyError::File {
            path: path.to_path_buf(),
            source,
        };
        let mut file = io::BufReader::new(File::open(path).map_err(file_error)?);
        let vocabulary = Self::read_from(&mut file)?;
        let mut extra = [0u8; 1];
        if file.read(&mut extra).map_err(file_error)? != 0 {
            return Err(VocabularyError::Corrupt(
                "trailing bytes after the checksum".into(),
            ));
        }
        Ok(vocabulary)
    }
}

/// `read_exact`, reporting the end of the data as truncation in `section`.
fn read_exact(
    r: &mut impl Read,
    buf: &mut [u8],
    section: &'static str,
) -> Result<(), VocabularyError> {
    r.read_exact(buf).map_err(|e| match e.kind() {
        io::ErrorKind::UnexpectedEof => VocabularyError::Truncated(section),
        _ => VocabularyError::Io(e),
    })
}

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

/// FNV-1a, 64 bits.
fn fnv1a(bytes: &[u8]) -> u64 {
    fnv1a_continue(FNV_OFFSET, bytes)
}

fn fnv1a_continue(mut hash: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        hash ^= u64::from(b);
        hash = hash.wrapping_mul(FNV_PRIME);
    }
    hash
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
