//! The dictionary's index: multi-index hashing over 256-bit codes with insertion and
//! deletion, and the linear scan it falls back to (module documentation of [`super`]).

use super::*;

/// Substrings (and hash tables) of the multi-index hash.
pub(super) const SUBSTRINGS: usize = 16;
/// Bits per substring.
pub(super) const SUBSTRING_BITS: u32 = 16;
/// Buckets per table.
pub(super) const BUCKETS: usize = 1 << SUBSTRING_BITS;
/// End of a bucket's list.
pub(super) const NIL: u32 = u32::MAX;
/// Seed of the fixed bit permutation (any constant; it only has to never change).
pub(super) const PERMUTATION_SEED: u64 = 0x424f_575f_4d49_4821; // "BOW_MIH!"
/// Cost of probing one bucket (a read of its head, at a random place in 4 MiB of tables),
/// in units of one distance of a linear scan. Sets only the choice between probing and
/// scanning ([`Dictionary::quantize`]), never a result.
pub(super) const PROBE_COST: f64 = 3.0;
/// Cost of one entry met in a probed bucket (its links and descriptor read at a random
/// place, a distance), in the same units.
pub(super) const ENTRY_COST: f64 = 6.0;
/// A quantisation scans instead of probing farther once the probes made per query would
/// exceed this share of a scan (module documentation).
pub(super) const PROBE_SHARE_OF_SCAN: f64 = 0.125;
/// Slots per block of a linear scan: 1024 descriptors, 32 KiB.
pub(super) const SCAN_BLOCK: usize = 1024;

/// A descriptor stored aligned to 32 bytes so that it never straddles a cache line.
#[derive(Clone, Copy)]
#[repr(align(32))]
pub(super) struct Aligned(pub(super) Descriptor);

/// The two best candidates seen so far, ordered by (distance, word id); empty entries have
/// distance `u32::MAX` and slot `NIL`.
#[derive(Clone, Copy)]
pub(super) struct Best {
    pub(super) distance: [u32; 2],
    pub(super) word: [WordId; 2],
    pub(super) slot: [u32; 2],
}

impl Best {
    pub(super) const EMPTY: Self = Self {
        distance: [u32::MAX; 2],
        word: [WordId::MAX; 2],
        slot: [NIL; 2],
    };

    pub(super) fn offer(&mut self, distance: u32, word: WordId, slot: u32) {
        if (distance, word) < (self.distance[0], self.word[0]) {
            self.distance = [distance, self.distance[0]];
            self.word = [word, self.word[0]];
            self.slot = [slot, self.slot[0]];
        } else if (distance, word) < (self.distance[1], self.word[1]) {
            self.distance[1] = distance;
            self.word[1] = word;
            self.slot[1] = slot;
        }
    }

    pub(super) fn get(&self, i: usize) -> Option<WordMatch> {
        (self.slot[i] != NIL).then(|| WordMatch {
            word: self.word[i],
            distance: self.distance[i],
        })
    }
}

/// Multi-index hashing over 256-bit codes with insertion and deletion (see the module
/// documentation). Entries live in slots, reused after deletion.
#[derive(Clone)]
pub(super) struct HammingIndex {
    /// For each descriptor bit (byte `b / 8`, bit `b % 8`): its substring and its bit there.
    pub(super) bit_map: [(u8, u8); DESCRIPTOR_BITS as usize],
    /// `masks[s]`: the 16-bit masks of exactly `s` bits, ascending, for `s ≤ probe radius`.
    pub(super) masks: Vec<Vec<u16>>,
    /// First slot of every bucket, table-major (`t · BUCKETS + key`); allocated on the first
    /// insertion.
    pub(super) heads: Vec<u32>,
    /// Next and previous slot in a bucket's list, slot-major (`slot · SUBSTRINGS + t`).
    pub(super) next: Vec<u32>,
    pub(super) prev: Vec<u32>,
    pub(super) descriptors: Vec<Aligned>,
    /// The word held by each slot (stale for free slots).
    pub(super) words: Vec<WordId>,
    /// Whether each slot holds a word (free slots keep a stale descriptor, which a scan
    /// passes over).
    pub(super) live: Vec<bool>,
    /// Free slots, reused last-freed first.
    pub(super) free: Vec<u32>,
}

impl HammingIndex {
    pub(super) fn new(probe_radius: u32) -> Self {
        // Fisher–Yates with splitmix64: position i of the permutation goes to substring
        // i / 16, bit i % 16.
        let mut order: Vec<usize> = (0..DESCRIPTOR_BITS as usize).collect();
        let mut state = PERMUTATION_SEED;
        for i in (1..order.len()).rev() {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^= z >> 31;
            order.swap(i, (z % (i as u64 + 1)) as usize);
        }
        let mut bit_map = [(0u8, 0u8); DESCRIPTOR_BITS as usize];
        for (position, &bit) in order.iter().enumerate() {
            bit_map[bit] = (
                (position / SUBSTRING_BITS as usize) as u8,
                (position % SUBSTRING_BITS as usize) as u8,
            );
        }
        let masks = (0..=probe_radius)
            .map(|s| {
                (0..=u16::MAX)
                    .filter(|m| m.count_ones() == s)
                    .collect::<Vec<_>>()
            })
            .collect();
        Self {
            bit_map,
            masks,
            heads: Vec::new(),
            next: Vec::new(),
            prev: Vec::new(),
            descriptors: Vec::new(),
            words: Vec::new(),
            live: Vec::new(),
            free: Vec::new(),
        }
    }

    /// Exactness radius `R`: every entry nearer than this to a query is examined.
    pub(super) fn radius(&self) -> u32 {
        SUBSTRING_BITS * self.masks.len() as u32
    }

    pub(super) fn keys(&self, d: &Descriptor) -> [u16; SUBSTRINGS] {
        let mut keys = [0u16; SUBSTRINGS];
        for (i, &byte) in d.iter().enumerate() {
            let mut b = byte;
            while b != 0 {
                let (t, p) = self.bit_map[i * 8 + b.trailing_zeros() as usize];
                keys[t as usize] |= 1 << p;
                b &= b - 1;
            }
        }
        keys
    }

    pub(super) fn insert(&mut self, d: &Descriptor, word: WordId) -> u32 {
        if self.heads.is_empty() {
            self.heads = vec![NIL; SUBSTRINGS * BUCKETS];
        }
        let slot = match self.free.pop() {
            Some(slot) => {
                self.descriptors[slot as usize] = Aligned(*d);
                self.words[slot as usize] = word;
                self.live[slot as usize] = true;
                slot
            }
            None => {
                let slot = u32::try_from(self.descriptors.len())
                    .ok()
                    .filter(|&s| s != NIL)
                    .expect("fewer than 2³² − 1 live words");
                self.descriptors.push(Aligned(*d));
                self.words.push(word);
                self.live.push(true);
                self.next.extend([NIL; SUBSTRINGS]);
                self.prev.extend([NIL; SUBSTRINGS]);
                slot
            }
        };
        for (t, key) in self.keys(d).into_iter().enumerate() {
            let head = &mut self.heads[t * BUCKETS + key as usize];
            let old = std::mem::replace(head, slot);
            let link = slot as usize * SUBSTRINGS + t;
            self.next[link] = old;
            self.prev[link] = NIL;
            if old != NIL {
                self.prev[old as usize * SUBSTRINGS + t] = slot;
            }
        }
        slot
    }

    pub(super) fn remove(&mut self, slot: u32) {
        let keys = self.keys(&self.descriptors[slot as usize].0);
        for (t, key) in keys.into_iter().enumerate() {
            let link = slot as usize * SUBSTRINGS + t;
            let (p, n) = (self.prev[link], self.next[link]);
            if p == NIL {
                self.heads[t * BUCKETS + key as usize] = n;
            } else {
                self.next[p as usize * SUBSTRINGS + t] = n;
            }
            if n != NIL {
                self.prev[n as usize * SUBSTRINGS + t] = p;
            }
        }
        self.live[slot as usize] = false;
        self.free.push(slot);
    }

    /// The two nearest entries within the radius, probing by increasing per-substring radius
    /// `s` up to `last`; after each `s`, `done(best, bound)` is asked whether to stop,
    /// knowing that every entry nearer than `bound = 16(s + 1)` has been examined. Entries
    /// at `R` or farther are never returned.
    pub(super) fn search(
        &self,
        q: &Descriptor,
        last: usize,
        mut done: impl FnMut(&Best, u32) -> bool,
    ) -> Best {
        let mut best = Best::EMPTY;
        if self.heads.is_empty() {
            return best;
        }
        let radius = self.radius();
        let keys = self.keys(q);
        for (s, masks) in self.masks.iter().enumerate().take(last + 1) {
            for (t, &key) in keys.iter().enumerate() {
                let table = &self.heads[t * BUCKETS..(t + 1) * BUCKETS];
                for &mask in masks {
                    let mut slot = table[(key ^ mask) as usize];
                    while slot != NIL {
                        // An entry may be met again through another substring.
                        if slot != best.slot[0] && slot != best.slot[1] {
                            let d = hamming(q, &self.descriptors[slot as usize].0);
                            if d < radius && d <= best.distance[1] {
                                best.offer(d, self.words[slot as usize], slot);
                            }
                        }
                        slot = self.next[slot as usize * SUBSTRINGS + t];
                    }
                }
            }
            if done(&best, SUBSTRING_BITS * (s as u32 + 1)) {
                break;
            }
        }
        best
    }

    /// Live entries.
    pub(super) fn len(&self) -> usize {
        self.descriptors.len() - self.free.len()
    }

    /// Estimated cost of probing per-substring radius `s` for one query, in units of one
    /// distance of a linear scan ([`PROBE_COST`], [`ENTRY_COST`]).
    pub(super) fn probe_cost(&self, s: usize) -> f64 {
        let probes = (SUBSTRINGS * self.masks[s].len()) as f64;
        probes * (PROBE_COST + ENTRY_COST * self.len() as f64 / BUCKETS as f64)
    }

    /// The two nearest entries within the radius of every query, by a linear scan: exactly
    /// what [`HammingIndex::search`] returns at the full radius. The scan runs over blocks of
    /// [`SCAN_BLOCK`] slots, each block passed by every query while it is in cache.
    pub(super) fn scan(&self, queries: &[&Descriptor]) -> Vec<Best> {
        let radius = self.radius();
        let lanes: Vec<[u64; 4]> = queries.iter().map(|&q| lanes(q)).collect();
        let mut bests = vec![Best::EMPTY; queries.len()];
        let mut distances = [0u32; SCAN_BLOCK];
        for (b, block) in self.descriptors.chunks(SCAN_BLOCK).enumerate() {
            let first = b * SCAN_BLOCK;
            let distances = &mut distances[..block.len()];
            for (q, best) in lanes.iter().zip(&mut bests) {
                // Distances first, in a loop of its own that the compiler can vectorise;
                // then the few that matter (most pairs lie about 128 bits apart).
                for (d, w) in distances.iter_mut().zip(block) {
                    *d = lane_distance(q, &w.0);
                }
                for (k, &d) in distances.iter().enumerate() {
                    let slot = first + k;
                    if d < radius && d <= best.distance[1] && self.live[slot] {
                        best.offer(d, self.words[slot], slot as u32);
                    }
                }
            }
        }
        bests
    }
}

/// A descriptor as four little-endian 64-bit lanes.
pub(super) fn lanes(d: &Descriptor) -> [u64; 4] {
    let lane = |i: usize| u64::from_le_bytes(d[8 * i..8 * i + 8].try_into().expect("8 bytes"));
    [lane(0), lane(1), lane(2), lane(3)]
}

/// Hamming distance between a descriptor in lanes and one in bytes.
pub(super) fn lane_distance(q: &[u64; 4], d: &Descriptor) -> u32 {
    let w = lanes(d);
    (q[0] ^ w[0]).count_ones()
        + (q[1] ^ w[1]).count_ones()
        + (q[2] ^ w[2]).count_ones()
        + (q[3] ^ w[3]).count_ones()
}

/// Whether `d1 < nndr · d2`.
pub(super) fn ratio_accepts(d1: u32, d2: u32, nndr: f32) -> bool {
    (d1 as f32) < nndr * d2 as f32
}

/// The outcome of the capped ratio test (module documentation) once it is certain, given
/// that every word nearer than `bound` has been examined: `Some(true)` to accept the nearest
/// candidate, `Some(false)` for a new word, `None` to search farther.
pub(super) fn ratio_outcome(best: &Best, bound: u32, radius: u32, nndr: f32) -> Option<bool> {
    let (d1, d2) = (best.distance[0], best.distance[1]);
    if d1 >= bound {
        // No certified nearest word yet; at the full radius there is none within R.
        return (bound >= radius).then_some(false);
    }
    if d2 < bound {
        // Both certified, and d2 < R.
        return Some(ratio_accepts(d1, d2, nndr));
    }
    // The true second distance is at least `bound`, so min(d2, R) ≥ bound.
    if ratio_accepts(d1, bound, nndr) {
        Some(true)
    } else {
        (bound >= radius).then_some(false)
    }
}
