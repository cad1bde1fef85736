//! [`Dictionary`]: an incremental bag-of-words dictionary of binary words (RTAB-Map's visual
//! word dictionary; a trained, hierarchical vocabulary is [`super::Vocabulary`]), with tf-idf
//! scoring, for appearance-based loop-closure detection as in RTAB-Map: Labbé and Michaud,
//! "Appearance-Based Loop Closure Detection for Online Large-Scale and Long-Term Operation",
//! IEEE Transactions on Robotics 29(3), 2013, and "Memory management for real-time
//! appearance-based loop closure detection", IEEE/RSJ IROS 2011.
//!
//! # The dictionary
//!
//! There is no pre-trained vocabulary: as in RTAB-Map's incremental dictionary, every
//! descriptor of a new location (a *signature*) either takes the nearest existing word or
//! becomes a word itself. A descriptor takes its nearest word `w₁` (at Hamming distance `d₁`)
//! when it passes Lowe's nearest-neighbour distance ratio test against the second-nearest
//! word (`d₂`): `d₁ < nndr · d₂` ([`DictionaryConfig::nndr`], RTAB-Map's `Kp/NndrRatio`).
//! The search is exact out to a radius `R` ([`Dictionary::search_radius`]) and certifies that
//! nothing else lies nearer than `R`, so the test actually applied is
//!
//! > accept `w₁` ⇔ `d₁ < nndr · min(d₂, R)`, with `d₂ = ∞` when the vocabulary holds a
//! > single word,
//!
//! which is Lowe's test wherever `d₂ < R`. Two consequences are deliberate: a descriptor
//! farther than `nndr · R` from every word always becomes a new word (such a "match" would be
//! meaningless for 256-bit descriptors, whose unrelated pairs lie about 128 bits apart), and
//! with a single word in the vocabulary the missing second neighbour counts as lying at `R`
//! (accept iff `d₁ < nndr · R`) rather than at infinity, which would let one word absorb
//! every descriptor. Ties in distance go to the smaller word id. The rule is a pure function
//! of the vocabulary's content, so a brute-force scan reproduces it exactly (the tests do).
//!
//! A signature's descriptors are all quantised against the vocabulary as it was *before*
//! the signature: descriptors of one signature never match each other's new words, so two
//! near-identical descriptors in one image that match nothing become two words. This keeps
//! the result independent of descriptor order.
//!
//! Every signature is indexed under its words in an inverted index (word → signatures with
//! their counts), and removing a signature — a location leaving working memory under
//! RTAB-Map's memory management — deletes the words no other signature references, from the
//! vocabulary and from its search structure. Word ids are never reused.
//!
//! # Scores and likelihood
//!
//! [`Dictionary::scores`] is the tf-idf vote of Sivic and Zisserman ("Video Google", ICCV
//! 2003) as RTAB-Map computes its raw likelihood: for every distinct word `w` of the query,
//! every considered signature `j` holding it receives `(n_wj / n_j) · ln(N / n_w)`, where
//! `n_wj` is how many of `j`'s descriptors were quantised to `w`, `n_j` is `j`'s number of
//! descriptors, `N` the number of considered signatures and `n_w` how many of them hold `w`.
//! Signatures the caller excludes (typically those in short-term memory) are treated as
//! absent from the collection: they count neither in `N` nor in `n_w`. The query's own word
//! frequencies do not weigh in (a repeated query word votes once), and the logarithm's base
//! is immaterial after [`adjusted_likelihood`], which is scale-invariant.
//!
//! [`adjusted_likelihood`] turns the raw scores into the likelihood of the Bayesian filter of
//! Labbé and Michaud (2013), after Angeli et al. ("A fast and incremental method for
//! loop-closure detection using bags of visual words", T-RO 2008): with `μ` and `σ` the mean
//! and standard deviation of the scores, `L(S_t|L_j) = (s_j − σ)/μ` if `s_j ≥ μ + σ` and `1`
//! otherwise, and the virtual "new place" gets `L(S_t|S₋₁) = μ/σ + 1`.
//!
//! # The nearest-neighbour index
//!
//! Quantisation runs at 1 Hz with ~500 descriptors per location against vocabularies of
//! 100k–200k words, so a linear scan is out. The index is multi-index hashing (Norouzi,
//! Punjani and Fleet, "Fast Search in Hamming Space with Multi-Index Hashing", CVPR 2012):
//! the 256 bits are split into `m = 16` disjoint substrings of 16 bits (after a fixed
//! pseudo-random permutation of the bits, so that correlated neighbouring bits do not share a
//! substring), and each substring value addresses a bucket in one of 16 direct-addressed
//! tables of 2¹⁶ buckets (doubly linked lists through the word slots, so insertion and
//! deletion are O(m)). By the pigeonhole principle, a word within Hamming distance
//! `16(r + 1) − 1` of the query agrees with it to within `r` bits on at least one substring,
//! so probing, in every table, all buckets within `r` bits of the query's substring finds
//! every such word: the search is *exact* within `R = 16(r + 1)`. Substrings of 16 bits ≈
//! log₂ of the vocabulary size is the paper's recommended choice, keeping buckets at about
//! one word. The search proceeds by increasing `r` (0, 1, … up to
//! [`DictionaryConfig::probe_radius`]) and stops as soon as the ratio test's outcome is
//! certain: a re-observed word (a few bits away, nearest well inside 16 bits) is settled by
//! the 16 exact-key probes of `r = 0`; a descriptor matching nothing costs the full
//! `16 · Σ_{s≤r} C(16, s)` probes (2192 at the default `r = 2`). This was preferred to
//! multi-probe LSH over sampled bits, which would be approximate with no distance
//! guarantee; MIH is deterministic, exact within `R`, and needs no tuning beyond `r`.
//!
//! # Probing or scanning
//!
//! At `r = 3` (`R = 64`, a quarter of the bits) MIH stops paying for descriptors that match
//! nothing: radius 3 alone probes `16 · C(16, 3) = 8960` buckets, each read at a random place
//! in 4 MiB of tables, and meets about 14 % of the vocabulary's entries, each read at a
//! random place too — more than a linear scan of every word, which reads them in order.
//! (Exact search at a quarter of the bits is in the regime where Norouzi et al.'s own
//! analysis gives no sublinear cost.) So [`Dictionary::quantize`] probes by increasing
//! radius only while probing is cheap, and settles the descriptors still undecided by one
//! linear scan of the vocabulary for all of them at once, block by block so that each block
//! of descriptors is read once from memory ([`Dictionary::scan_from`] says where it
//! switches). Both are exact within `R`, so the quantisation is the same word for word; only
//! the time differs. RTAB-Map offers the same two kinds of search for its dictionary
//! (`Kp/NNStrategy`: FLANN structures, or `kNNBruteForce`, a linear scan).

use std::collections::BTreeMap;
use std::fmt;

use serde::Deserialize;

mod index;

use index::*;

/// A 256-bit binary descriptor (BRIEF, ORB), compared by Hamming distance.
pub type Descriptor = [u8; 32];
/// A visual word, numbered from 0 in order of creation; ids are never reused.
pub type WordId = u32;
/// A location's signature, named by the caller.
pub type SignatureId = u64;

/// Bits in a [`Descriptor`].
pub const DESCRIPTOR_BITS: u32 = 256;
/// The largest accepted [`DictionaryConfig::probe_radius`].
pub const MAX_PROBE_RADIUS: u32 = 3;

/// Hamming distance between two descriptors.
pub fn hamming(a: &Descriptor, b: &Descriptor) -> u32 {
    a.chunks_exact(8)
        .zip(b.chunks_exact(8))
        .map(|(x, y)| {
            let x = u64::from_le_bytes(x.try_into().expect("8 bytes"));
            let y = u64::from_le_bytes(y.try_into().expect("8 bytes"));
            (x ^ y).count_ones()
        })
        .sum()
}

/// Parameters of a [`Dictionary`].
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DictionaryConfig {
    /// Nearest-neighbour distance ratio: a descriptor takes its nearest word only if that
    /// word is nearer than `nndr` times the second-nearest (RTAB-Map's `Kp/NndrRatio`,
    /// default 0.8). In (0, 1].
    pub nndr: f32,
    /// Per-substring probe radius `r` of the multi-index hash, 0 to [`MAX_PROBE_RADIUS`]:
    /// the search is exact within `R = 16(r + 1)` bits, so descriptors farther than
    /// `nndr · R` from every word become new words. The default 2 gives `R = 48` and a
    /// largest accepted distance of 38 bits at `nndr = 0.8`; each step up multiplies the cost
    /// of a descriptor that matches nothing by about 5–8.
    pub probe_radius: u32,
}

impl Default for DictionaryConfig {
    fn default() -> Self {
        Self {
            nndr: 0.8,
            probe_radius: 2,
        }
    }
}

/// A word found near a query descriptor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WordMatch {
    pub word: WordId,
    /// Hamming distance to the query.
    pub distance: u32,
}

/// One posting of the inverted index: a signature holding the word.
#[derive(Debug, Clone, Copy)]
struct Posting {
    signature: SignatureId,
    /// `n_wj`: the signature's descriptors quantised to the word.
    count: u32,
    /// `n_j`: the signature's number of descriptors.
    length: u32,
}

/// An indexed signature.
#[derive(Debug, Clone)]
struct Signature {
    /// Its distinct words with their counts, by word id.
    words: Vec<(WordId, u32)>,
}

/// The incremental vocabulary with its inverted index (see the module documentation).
#[derive(Clone)]
pub struct Dictionary {
    config: DictionaryConfig,
    index: HammingIndex,
    /// Live words and their slots in the index.
    slots: BTreeMap<WordId, u32>,
    /// Postings of the word in each slot, by signature id (empty for free slots).
    postings: Vec<Vec<Posting>>,
    signatures: BTreeMap<SignatureId, Signature>,
    next_word: WordId,
}

impl fmt::Debug for Dictionary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Dictionary")
            .field("config", &self.config)
            .field("words", &self.word_count())
            .field("signatures", &self.signature_count())
            .field("next_word", &self.next_word)
            .finish_non_exhaustive()
    }
}

impl Default for Dictionary {
    fn default() -> Self {
        Self::new(DictionaryConfig::default())
    }
}

impl Dictionary {
    /// An empty vocabulary.
    ///
    /// # Panics
    /// If `nndr` is not in (0, 1] or `probe_radius` exceeds [`MAX_PROBE_RADIUS`].
    pub fn new(config: DictionaryConfig) -> Self {
        assert!(
            config.nndr > 0.0 && config.nndr <= 1.0,
            "nndr must be in (0, 1], got {}",
            config.nndr
        );
        assert!(
            config.probe_radius <= MAX_PROBE_RADIUS,
            "probe_radius must be at most {MAX_PROBE_RADIUS}, got {}",
            config.probe_radius
        );
        Self {
            config,
            index: HammingIndex::new(config.probe_radius),
            slots: BTreeMap::new(),
            postings: Vec::new(),
            signatures: BTreeMap::new(),
            next_word: 0,
        }
    }

    pub fn config(&self) -> &DictionaryConfig {
        &self.config
    }

    /// `R = 16(probe_radius + 1)`: every word nearer than this to a query is found exactly;
    /// descriptors farther than `nndr · R` from every word never match.
    pub fn search_radius(&self) -> u32 {
        self.index.radius()
    }

    /// Quantises a new signature's descriptors and indexes the signature under the words.
    ///
    /// Each descriptor takes its nearest word if it passes the capped ratio test (module
    /// documentation), otherwise it becomes a new word. All descriptors are quantised against
    /// the vocabulary as it was before this call, so they never match one another's new
    /// words; new words are numbered in descriptor order. Returns one word per descriptor.
    /// An `id` already indexed is replaced, as by [`Dictionary::remove_signature`] first.
    ///
    /// # Panics
    /// If the 2³² word ids are exhausted or a signature has 2³² descriptors or more.
    pub fn add_signature(&mut self, id: SignatureId, descriptors: &[Descriptor]) -> Vec<WordId> {
        self.remove_signature(id);
        let length = u32::try_from(descriptors.len()).expect("fewer than 2³² descriptors");
        let quantised = self.quantize(descriptors);
        let ids: Vec<WordId> = descriptors
            .iter()
            .zip(quantised)
            .map(|(d, q)| q.unwrap_or_else(|| self.new_word(d)))
            .collect();

        let mut sorted = ids.clone();
        sorted.sort_unstable();
        let mut words: Vec<(WordId, u32)> = Vec::new();
        for w in sorted {
            match words.last_mut() {
                Some((last, count)) if *last == w => *count += 1,
                _ => words.push((w, 1)),
            }
        }
        for &(w, count) in &words {
            let postings = &mut self.postings[self.slots[&w] as usize];
            let at = postings.partition_point(|p| p.signature < id);
            postings.insert(
                at,
                Posting {
                    signature: id,
                    count,
                    length,
                },
            );
        }
        self.signatures.insert(id, Signature { words });
        ids
    }

    fn new_word(&mut self, d: &Descriptor) -> WordId {
        let w = self.next_word;
        self.next_word = w.checked_add(1).expect("word ids exhausted");
        let slot = self.index.insert(d, w) as usize;
        if slot >= self.postings.len() {
            self.postings.resize_with(slot + 1, Vec::new);
        }
        self.slots.insert(w, slot as u32);
        w
    }

    /// Quantises descriptors without changing anything: the word each would take in
    /// [`Dictionary::add_signature`], or `None` where it would become a new word.
    ///
    /// Each descriptor is first looked up in the multi-index hash by increasing probe radius
    /// while probing is cheap; those still undecided at [`Dictionary::scan_from`] are settled
    /// by one linear scan of the vocabulary for all of them (module documentation). Both are
    /// exact within the search radius, so the choice changes the time taken, never a word.
    pub fn quantize(&self, descriptors: &[Descriptor]) -> Vec<Option<WordId>> {
        let (radius, nndr) = (self.index.radius(), self.config.nndr);
        let probed = self.scan_from().unwrap_or(self.index.masks.len());
        let mut out = vec![None; descriptors.len()];
        let mut undecided = Vec::new();
        for (i, d) in descriptors.iter().enumerate() {
            if probed == 0 {
                undecided.push(i);
                continue;
            }
            let mut outcome = None;
            let best = self.index.search(d, probed - 1, |best, bound| {
                outcome = ratio_outcome(best, bound, radius, nndr);
                outcome.is_some()
            });
            match outcome {
                Some(accept) => out[i] = accept.then_some(best.word[0]),
                None => undecided.push(i),
            }
        }
        let queries: Vec<&Descriptor> = undecided.iter().map(|&i| &descriptors[i]).collect();
        for (&i, best) in undecided.iter().zip(self.index.scan(&queries)) {
            // Every word nearer than R examined: the outcome is certain.
            let accept = ratio_outcome(&best, radius, radius, nndr) == Some(true);
            out[i] = accept.then_some(best.word[0]);
        }
        out
    }

    /// The probe radius from which [`Dictionary::quantize`] scans instead of probing, for the
    /// vocabulary's present size; `None` when it probes all the way to
    /// [`DictionaryConfig::probe_radius`]. It probes to the end if that costs no more per
    /// query than a scan; otherwise it probes the radii that together cost at most
    /// [`PROBE_SHARE_OF_SCAN`] of a scan (they settle re-observed words, a few bits away)
    /// and scans for the rest. Costs are estimated from the expected bucket load.
    pub fn scan_from(&self) -> Option<usize> {
        let index = &self.index;
        let scan = index.len() as f64;
        let costs: Vec<f64> = (0..index.masks.len())
            .map(|s| index.probe_cost(s))
            .collect();
        let mut spent = 0.0;
        for (s, cost) in costs.iter().enumerate() {
            if costs[s..].iter().sum::<f64>() <= scan {
                return None;
            }
            spent += cost;
            if spent > PROBE_SHARE_OF_SCAN * scan {
                return Some(s);
            }
        }
        None
    }

    /// The two nearest words to `d` that lie nearer than [`Dictionary::search_radius`],
    /// nearest first (ties to the smaller id); exact, i.e. what a linear scan restricted to
    /// that radius returns.
    pub fn nearest(&self, d: &Descriptor) -> [Option<WordMatch>; 2] {
        let last = self.index.masks.len() - 1;
        let best = self
            .index
            .search(d, last, |best, bound| best.distance[1] < bound);
        [best.get(0), best.get(1)]
    }

    /// Removes a signature from the inverted index (a location leaving working memory) and
    /// deletes the words no other signature references. Unknown ids are ignored.
    pub fn remove_signature(&mut self, id: SignatureId) {
        let Some(signature) = self.signatures.remove(&id) else {
            return;
        };
        for (w, _) in signature.words {
            let slot = self.slots[&w];
            let postings = &mut self.postings[slot as usize];
            let at = postings.partition_point(|p| p.signature < id);
            postings.remove(at);
            if postings.is_empty() {
                self.index.remove(slot);
                self.slots.remove(&w);
            }
        }
    }

    /// tf-idf score of every indexed signature not `exclude`d that shares a word with the
    /// query `words`: `s_j = Σ_{w ∈ words, distinct} (n_wj / n_j) · ln(N / n_w)`, with
    /// `n_wj` the count of `w` in `j`, `n_j` the number of `j`'s descriptors, `N` the number
    /// of signatures not excluded and `n_w` how many of them hold `w` (module documentation).
    /// Unknown and repeated query words are ignored. A signature sharing only words every
    /// considered signature holds scores 0 and is listed. Sorted by signature id; sums are
    /// accumulated in ascending word order, so the result is deterministic.
    pub fn scores(
        &self,
        words: &[WordId],
        exclude: impl Fn(SignatureId) -> bool,
    ) -> Vec<(SignatureId, f64)> {
        let considered = self.signatures.keys().filter(|&&j| !exclude(j)).count();
        if considered == 0 {
            return Vec::new();
        }
        let mut query = words.to_vec();
        query.sort_unstable();
        query.dedup();
        let mut votes: Vec<(SignatureId, f64)> = Vec::new();
        let mut holders: Vec<Posting> = Vec::new();
        for w in query {
            let Some(&slot) = self.slots.get(&w) else {
                continue;
            };
            holders.clear();
            holders.extend(
                self.postings[slot as usize]
                    .iter()
                    .filter(|p| !exclude(p.signature)),
            );
            if holders.is_empty() {
                continue;
            }
            let idf = (considered as f64 / holders.len() as f64).ln();
            votes.extend(
                holders
                    .iter()
                    .map(|p| (p.signature, f64::from(p.count) / f64::from(p.length) * idf)),
            );
        }
        // Stable: each signature's votes stay in word order.
        votes.sort_by_key(|&(j, _)| j);
        let mut scores: Vec<(SignatureId, f64)> = Vec::new();
        for (j, v) in votes {
            match scores.last_mut() {
                Some((last, s)) if *last == j => *s += v,
                _ => scores.push((j, v)),
            }
        }
        scores
    }

    /// Number of live words.
    pub fn word_count(&self) -> usize {
        self.slots.len()
    }

    /// Number of indexed signatures.
    pub fn signature_count(&self) -> usize {
        self.signatures.len()
    }

    /// A live word's descriptor (the descriptor that created it).
    pub fn descriptor(&self, w: WordId) -> Option<&Descriptor> {
        self.slots
            .get(&w)
            .map(|&slot| &self.index.descriptors[slot as usize].0)
    }

    /// Every live word with its descriptor, by id.
    pub fn words(&self) -> impl Iterator<Item = (WordId, &Descriptor)> + '_ {
        self.slots
            .iter()
            .map(|(&w, &slot)| (w, &self.index.descriptors[slot as usize].0))
    }

    /// Whether a signature is indexed.
    pub fn contains_signature(&self, id: SignatureId) -> bool {
        self.signatures.contains_key(&id)
    }

    /// An indexed signature's distinct words with their counts, by word id.
    pub fn signature_words(&self, id: SignatureId) -> Option<&[(WordId, u32)]> {
        self.signatures.get(&id).map(|s| s.words.as_slice())
    }
}

/// The likelihood of Labbé and Michaud (2013) from raw [`Dictionary::scores`]: returns
/// `L(S_t|L_j)` for every input entry, in input order, and the likelihood `L(S_t|S₋₁)` of
/// the virtual "new place".
///
/// With `μ` and `σ` the mean and (population) standard deviation of the positive, finite
/// scores, `L_j = (s_j − σ)/μ` if `s_j ≥ μ + σ` and `1` otherwise, and the new place gets
/// `μ/σ + 1`: it is likely when no location stands out (small `σ` relative to `μ`). Scores
/// that are zero, negative or not finite carry no evidence: they are left out of `μ` and `σ`
/// and get `L_j = 1`. When the statistics are degenerate — no positive score, or `σ = 0`
/// (a single candidate, or all equal; taken as `σ ≤ 10⁻¹² μ` against rounding) — no location
/// can stand out and the formula for the new place diverges; everything, the new place
/// included, then gets 1, so that the filter keeps its prediction.
pub fn adjusted_likelihood(scores: &[(SignatureId, f64)]) -> (Vec<(SignatureId, f64)>, f64) {
    let evidence = |s: f64| s.is_finite() && s > 0.0;
    let (mut n, mut sum) = (0usize, 0.0);
    for &(_, s) in scores.iter().filter(|&&(_, s)| evidence(s)) {
        n += 1;
        sum += s;
    }
    let neutral = || (scores.iter().map(|&(j, _)| (j, 1.0)).collect(), 1.0);
    if n == 0 {
        return neutral();
    }
    let mean = sum / n as f64;
    let variance = scores
        .iter()
        .filter(|&&(_, s)| evidence(s))
        .map(|&(_, s)| (s - mean).powi(2))
        .sum::<f64>()
        / n as f64;
    let sigma = variance.sqrt();
    if sigma <= 1e-12 * mean {
        return neutral();
    }
    let likelihood = scores
        .iter()
        .map(|&(j, s)| {
            let l = if evidence(s) && s >= mean + sigma {
                (s - sigma) / mean
            } else {
                1.0
            };
            (j, l)
        })
        .collect();
    (likelihood, mean / sigma + 1.0)
}
