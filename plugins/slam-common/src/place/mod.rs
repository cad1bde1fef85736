//! Place recognition: has the robot been here before?
//!
//! - [`bow`]: [`Dictionary`], an incremental bag-of-words dictionary of binary words with
//!   tf-idf scores and RTAB-Map's likelihood, for appearance-based loop-closure detection;
//! - [`vocabulary`]: [`Vocabulary`], a trained hierarchical vocabulary of binary words (DBoW2,
//!   as ORB-SLAM2 uses it) with tf-idf bag-of-words vectors, the direct index and the L1
//!   score;
//! - [`m2dp`]: the M2DP global descriptor of a 3D point cloud (He, Wang and Zhang 2016), for
//!   lidar place recognition;
//! - [`scan_context`]: Scan Context (Kim and Kim 2018), a polar descriptor of a 3D scan whose
//!   match also gives the heading, and a database searched by its ring key.

pub mod bow;
pub mod m2dp;
pub mod scan_context;
pub mod vocabulary;

pub use bow::{Dictionary, DictionaryConfig, SignatureId, WordMatch, adjusted_likelihood, hamming};
pub use m2dp::M2dpConfig;
pub use scan_context::{PlaceMatch, ScanContext, ScanContextConfig, ScanContextDatabase};
pub use vocabulary::{BowVector, FeatureVector, TrainConfig, Vocabulary, VocabularyError};
