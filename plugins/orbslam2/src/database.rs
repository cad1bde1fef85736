//! The keyframe database: an inverted file from each vocabulary word to the keyframes that
//! contain it (DBoW2, Gálvez-López and Tardós 2012, §IV), queried as ORB-SLAM2 does for
//! loop and relocalisation candidates (ORB-SLAM, T-RO 2015, §VII-A): keyframes sharing
//! words with the query; those with at least 80 % of the most shared words are scored; each
//! score is accumulated over the keyframe's 10 best covisibles; groups scoring at least 75 %
//! of the best group give their best keyframe.

use std::collections::{BTreeMap, BTreeSet};

use slam_common::place::vocabulary::{BowVector, Vocabulary, WordId};

use crate::map::Map;

#[derive(Debug, Clone, Default)]
pub struct KeyFrameDatabase {
    inverted: BTreeMap<WordId, Vec<usize>>,
}

impl KeyFrameDatabase {
    pub fn add(&mut self, map: &Map, kf: usize) {
        for &(w, _) in &map.keyframes[kf].frame.bow.entries {
            self.inverted.entry(w).or_default().push(kf);
        }
    }

    pub fn erase(&mut self, map: &Map, kf: usize) {
        for &(w, _) in &map.keyframes[kf].frame.bow.entries {
            if let Some(list) = self.inverted.get_mut(&w) {
                list.retain(|&k| k != kf);
            }
        }
    }

    /// Candidates for `bow` (loop detection or relocalisation), best group first.
    pub fn candidates(
        &self,
        map: &Map,
        bow: &BowVector,
        exclude: &BTreeSet<usize>,
        min_score: f64,
        common_words_ratio: f64,
        group_score_ratio: f64,
    ) -> Vec<usize> {
        let mut common: BTreeMap<usize, usize> = BTreeMap::new();
        for &(w, _) in &bow.entries {
            for &kf in self.inverted.get(&w).map(Vec::as_slice).unwrap_or_default() {
                if !exclude.contains(&kf) && !map.keyframes[kf].bad {
                    *common.entry(kf).or_default() += 1;
                }
            }
        }
        let Some(&max_common) = common.values().max() else {
            return Vec::new();
        };
        let min_common = common_words_ratio * max_common as f64;
        let mut scores: BTreeMap<usize, f64> = BTreeMap::new();
        for (&kf, &n) in &common {
            if n as f64 > min_common {
                let s = Vocabulary::score(bow, &map.keyframes[kf].frame.bow);
                if s >= min_score {
                    scores.insert(kf, s);
                }
            }
        }
        let mut groups: Vec<(f64, usize)> = Vec::new();
        let mut best_acc = 0.0f64;
        for (&kf, &s) in &scores {
            let mut acc = s;
            let mut best = (s, kf);
            for n in map.keyframes[kf].best_covisibles(10) {
                if let Some(&sn) = scores.get(&n) {
                    acc += sn;
                    if sn > best.0 {
                        best = (sn, n);
                    }
                }
            }
            best_acc = best_acc.max(acc);
            groups.push((acc, best.1));
        }
        let threshold = group_score_ratio * best_acc;
        groups.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut out = Vec::new();
        for (acc, kf) in groups {
            if acc >= threshold && !out.contains(&kf) {
                out.push(kf);
            }
        }
        out
    }
}
