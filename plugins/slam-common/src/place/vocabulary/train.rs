//! Training: hierarchical k-means over binary descriptors, k-means++ seeds and per-bit
//! median centres (module documentation of [`super`]).

use super::*;

/// `SPREAD[b]` has byte `j` equal to bit `j` of `b`: adding it to a `u64` counts the bits of
/// a descriptor byte in eight byte-wide counters at once.
pub(super) const SPREAD: [u64; 256] = {
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
pub(super) struct BitCounts {
    pub(super) counts: Vec<[u32; 256]>,
    pub(super) sizes: Vec<u32>,
}

impl BitCounts {
    pub(super) fn new(clusters: usize) -> Self {
        Self {
            counts: vec![[0; 256]; clusters],
            sizes: vec![0; clusters],
        }
    }

    /// Counts of `points` labelled `labels`: byte-wide counters flushed every 255 additions.
    pub(super) fn of(points: &[Bits], labels: &[u32], clusters: usize) -> Self {
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

    pub(super) fn add(mut self, other: Self) -> Self {
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
    pub(super) fn median(&self, c: usize) -> Option<Bits> {
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
pub(super) fn assign(points: &[Bits], centres: &[Bits]) -> Vec<u32> {
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
pub(super) fn bit_counts(points: &[Bits], labels: &[u32], clusters: usize) -> BitCounts {
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
pub(super) fn lower_distances(points: &[Bits], d2: &mut [u64], centre: &Bits) {
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
pub(super) fn seeds(points: &[Bits], k: usize, rng: &mut ChaCha8Rng) -> Vec<Bits> {
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
pub(super) struct Child {
    pub(super) centre: Bits,
    pub(super) members: Vec<Bits>,
}

/// The distinct values of `points` in order of first occurrence, if there are at most `k`.
pub(super) fn few_distinct(points: &[Bits], k: usize) -> Option<Vec<Bits>> {
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
pub(super) fn split(points: Vec<Bits>, config: &TrainConfig, node: NodeId) -> Vec<Child> {
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
    pub(super) fn from_tree(
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
}
