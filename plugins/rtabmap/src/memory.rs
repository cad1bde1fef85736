//! Locations and RTAB-Map's memory management (Labbé and Michaud, "Memory management for
//! real-time appearance-based loop closure detection", IROS 2011; T-RO 2013, §III-A): a new
//! location first enters short-term memory (STM), whose locations are never loop-closure
//! candidates since they look like the current image anyway; when STM is full its oldest
//! location moves to working memory (WM), where it is a candidate; with a WM limit, the
//! oldest WM locations move on to long-term memory (LTM) and leave the vocabulary and the
//! Bayes filter. (RTAB-Map picks what to transfer by a weight grown by rehearsal; there is no
//! rehearsal here, so the oldest go.)

use std::collections::{BTreeSet, VecDeque};

use nalgebra::{Isometry3, Vector2, Vector3};
use slam_common::bow::{SignatureId, Vocabulary, VocabularyConfig, WordId};

use crate::bayes::{BayesFilter, Posterior};
use crate::config::{LoopClosureConfig, MemoryConfig};
use crate::features::Features;

/// A node of the map.
#[derive(Debug, Clone)]
pub struct Location {
    pub id: u64,
    pub stamp_ns: i64,
    /// Where odometry put the base when the location was made.
    pub odom_from_base: Isometry3<f64>,
    /// The strongest features, with their visual word each.
    pub features: Features,
    pub words: Vec<WordId>,
    /// The 2D scan nearest in time, in the scan's frame, if one was recent.
    pub scan: Option<Vec<Vector2<f64>>>,
    /// Decimated depth points in the base frame, for the map cloud.
    pub cloud: Vec<Vector3<f32>>,
}

/// The loop-closure hypothesis for a new location, if any passed the threshold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hypothesis {
    pub id: u64,
    pub posterior: f64,
}

#[derive(Debug)]
pub struct Memory {
    cfg: MemoryConfig,
    vocabulary: Vocabulary,
    bayes: BayesFilter,
    threshold: f64,
    locations: Vec<Location>,
    stm: VecDeque<u64>,
    wm: BTreeSet<u64>,
    ltm: usize,
}

impl Memory {
    pub fn new(cfg: &MemoryConfig, loops: &LoopClosureConfig) -> Self {
        Self {
            cfg: cfg.clone(),
            vocabulary: Vocabulary::new(VocabularyConfig {
                nndr: cfg.word_nndr,
                probe_radius: cfg.word_probe_radius,
            }),
            bayes: BayesFilter::new(loops.prediction.clone(), loops.virtual_place_prior),
            threshold: loops.hypothesis_threshold,
            locations: Vec::new(),
            stm: VecDeque::new(),
            wm: BTreeSet::new(),
            ltm: 0,
        }
    }

    pub fn locations(&self) -> &[Location] {
        &self.locations
    }

    /// Location `id` (ids are their index).
    pub fn location(&self, id: u64) -> &Location {
        &self.locations[id as usize]
    }

    pub fn last(&self) -> Option<&Location> {
        self.locations.last()
    }

    pub fn next_id(&self) -> u64 {
        self.locations.len() as u64
    }

    pub fn word_count(&self) -> usize {
        self.vocabulary.word_count()
    }

    pub fn working_memory(&self) -> usize {
        self.wm.len()
    }

    /// Adds a location: quantises its features into words, and (with `detect`) runs the
    /// Bayes filter over working memory. Returns the posterior and the hypothesis above the
    /// threshold, if any. The location then enters STM.
    pub fn add(
        &mut self,
        mut location: Location,
        detect: bool,
    ) -> (Option<Posterior>, Option<Hypothesis>) {
        let id = location.id;
        debug_assert_eq!(id, self.next_id());
        location.words = self
            .vocabulary
            .add_signature(id as SignatureId, &location.features.descriptors);
        let mut result = (None, None);
        if detect && !self.wm.is_empty() {
            let wm = &self.wm;
            let raw = self
                .vocabulary
                .scores(&location.words, |s| !wm.contains(&s));
            // Every WM location, with 0 for those sharing no word.
            let mut scores: Vec<(u64, f64)> = wm.iter().map(|&i| (i, 0.0)).collect();
            for (s, v) in raw {
                if let Ok(k) = scores.binary_search_by_key(&s, |(i, _)| *i) {
                    scores[k].1 = v;
                }
            }
            let (likelihood, virtual_likelihood) = slam_common::bow::adjusted_likelihood(&scores);
            let posterior = self.bayes.update(&likelihood, virtual_likelihood);
            let hypothesis = posterior
                .best()
                .filter(|(_, p)| *p >= self.threshold)
                .map(|(id, posterior)| Hypothesis { id, posterior });
            result = (Some(posterior), hypothesis);
        }
        self.locations.push(location);
        self.stm.push_back(id);
        while self.stm.len() > self.cfg.short_term_memory {
            let oldest = self.stm.pop_front().expect("STM is not empty");
            self.wm.insert(oldest);
        }
        if self.cfg.working_memory_limit > 0 {
            while self.wm.len() > self.cfg.working_memory_limit {
                let oldest = *self.wm.first().expect("WM is not empty");
                self.wm.remove(&oldest);
                self.vocabulary.remove_signature(oldest as SignatureId);
                self.bayes.remove(oldest);
                self.ltm += 1;
            }
        }
        result
    }

    /// Correspondences for geometric verification of `old` against `new`: words that occur
    /// exactly once in each (RTAB-Map's unique-word matching), as (old's 3D point in its
    /// optical frame, new's pixel).
    pub fn correspondences(&self, old: u64, new: u64) -> (Vec<Vector3<f64>>, Vec<[f32; 2]>) {
        let (a, b) = (self.location(old), self.location(new));
        let unique = |l: &Location| {
            let mut sorted: Vec<(WordId, usize)> = l.words.iter().copied().zip(0..).collect();
            sorted.sort_unstable();
            let mut out = Vec::new();
            for (k, &(w, i)) in sorted.iter().enumerate() {
                let dup_prev = k > 0 && sorted[k - 1].0 == w;
                let dup_next = k + 1 < sorted.len() && sorted[k + 1].0 == w;
                if !dup_prev && !dup_next {
                    out.push((w, i));
                }
            }
            out
        };
        let (ua, ub) = (unique(a), unique(b));
        let (mut object, mut pixels) = (Vec::new(), Vec::new());
        let (mut i, mut j) = (0, 0);
        while i < ua.len() && j < ub.len() {
            match ua[i].0.cmp(&ub[j].0) {
                std::cmp::Ordering::Less => i += 1,
                std::cmp::Ordering::Greater => j += 1,
                std::cmp::Ordering::Equal => {
                    if let Some(p) = a.features.points[ua[i].1] {
                        object.push(p);
                        pixels.push(b.features.pixels[ub[j].1]);
                    }
                    i += 1;
                    j += 1;
                }
            }
        }
        (object, pixels)
    }
}
