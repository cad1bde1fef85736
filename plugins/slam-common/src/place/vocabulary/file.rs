//! The vocabulary's file: the documented binary format, read back with every check, and
//! DBoW2's text format for comparison (module documentation of [`super`]).

use super::*;

impl Vocabulary {
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
pub(super) fn read_exact(
    r: &mut impl Read,
    buf: &mut [u8],
    section: &'static str,
) -> Result<(), VocabularyError> {
    r.read_exact(buf).map_err(|e| match e.kind() {
        io::ErrorKind::UnexpectedEof => VocabularyError::Truncated(section),
        _ => VocabularyError::Io(e),
    })
}

pub(super) const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
pub(super) const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

/// FNV-1a, 64 bits.
pub(super) fn fnv1a(bytes: &[u8]) -> u64 {
    fnv1a_continue(FNV_OFFSET, bytes)
}

pub(super) fn fnv1a_continue(mut hash: u64, bytes: &[u8]) -> u64 {
    for &b in bytes {
        hash ^= u64::from(b);
        hash = hash.wrapping_mul(FNV_PRIME);
    }
    hash
}
