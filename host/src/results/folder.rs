//! A results folder (a bench's, a run's) is written under a temporary name beside its target
//! and moved into place in one `rename` when complete, so an interrupted or failed bench never
//! leaves half-written results; a marker file says a folder is vinebench's, so a rerun may
//! replace it and nothing else is ever removed.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;

/// Marks a folder as a vinebench results folder, so a rerun may replace it.
pub const MARKER: &str = ".vinebench-results";
/// Marks a folder as a sweep folder, so a sweep may resume in it.
pub const SWEEP_MARKER: &str = ".vinebench-sweep";
/// Marks a bench's resumable folder ([`Staging::begin_resumable`]); holds its fingerprint.
pub const PARTIAL: &str = ".vinebench-partial";

/// Where a bench writing `target` keeps its runs until it is complete: `.<name>.partial`.
pub fn partial_path(target: &Path) -> PathBuf {
    target.with_file_name(format!(".{}.partial", folder_name(target)))
}

/// Whether `dir` is a sweep's folder (it has the sweep's marker file).
pub fn is_sweep_folder(dir: &Path) -> bool {
    dir.join(SWEEP_MARKER).exists()
}

/// A results folder being written: [`Staging::dir`] until [`Staging::commit`] moves it to
/// its target; dropped uncommitted, it is removed.
#[derive(Debug)]
pub struct Staging {
    target: PathBuf,
    tmp: PathBuf,
    committed: bool,
}

/// The last component of a results folder's path (`results` if it has none).
pub fn folder_name(out: &Path) -> String {
    out.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "results".into())
}

impl Staging {
    /// Starts writing `target`, which must be absent, empty or a vinebench results folder.
    pub fn begin(target: &Path) -> anyhow::Result<Self> {
        Self::check_target(target)?;
        let tmp = target.with_file_name(format!(
            ".{}.tmp-{}",
            folder_name(target),
            std::process::id()
        ));
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp).with_context(|| tmp.display().to_string())?;
        }
        std::fs::create_dir_all(&tmp).with_context(|| tmp.display().to_string())?;
        Ok(Self {
            target: target.to_owned(),
            tmp,
            committed: false,
        })
    }

    /// Where the folder is being written.
    pub fn dir(&self) -> &Path {
        &self.tmp
    }

    /// The folder's final path.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Starts writing `target` in a resumable folder beside it, `.<name>.partial`, marked
    /// with `fingerprint` (what determines its runs): if one with the same fingerprint is
    /// there (a bench interrupted by Ctrl-C, or one whose supervisor died), it is taken up
    /// again, with the runs it holds; one with another fingerprint is replaced. Unlike
    /// [`Staging::begin`]'s, the folder is not removed when dropped uncommitted: it is kept
    /// for the next run of the same bench (or removed by [`Staging::discard`]). The second
    /// value says whether it was taken up again.
    pub fn begin_resumable(target: &Path, fingerprint: &str) -> anyhow::Result<(Self, bool)> {
        Self::check_target(target)?;
        let partial = partial_path(target);
        let marker = partial.join(PARTIAL);
        let mut resumed = false;
        if partial.exists() {
            match std::fs::read_to_string(&marker) {
                Ok(text) if text.trim() == fingerprint => resumed = true,
                Ok(_) => std::fs::remove_dir_all(&partial)
                    .with_context(|| partial.display().to_string())?,
                Err(_) => anyhow::bail!(
                    "{} exists and is not a vinebench partial folder; remove it",
                    partial.display()
                ),
            }
        }
        if !resumed {
            std::fs::create_dir_all(&partial).with_context(|| partial.display().to_string())?;
            std::fs::write(&marker, fingerprint).with_context(|| marker.display().to_string())?;
        }
        Ok((
            Self {
                target: target.to_owned(),
                tmp: partial,
                // Kept when dropped: what has finished stays for a resume.
                committed: true,
            },
            resumed,
        ))
    }

    /// Removes the folder being written (nothing in it is worth keeping).
    pub fn discard(self) -> anyhow::Result<()> {
        if self.tmp.exists() {
            std::fs::remove_dir_all(&self.tmp).with_context(|| self.tmp.display().to_string())?;
        }
        Ok(())
    }

    fn check_target(target: &Path) -> anyhow::Result<()> {
        if target.exists()
            && !target.join(MARKER).exists()
            && std::fs::read_dir(target)
                .with_context(|| target.display().to_string())?
                .next()
                .is_some()
        {
            anyhow::bail!(
                "{} exists and is not a vinebench results folder; choose another --out",
                target.display()
            );
        }
        Ok(())
    }

    /// Marks the folder, replaces the target with it and points `latest` beside it at it.
    pub fn commit(mut self) -> anyhow::Result<PathBuf> {
        let _ = std::fs::remove_file(self.tmp.join(PARTIAL));
        std::fs::File::create(self.tmp.join(MARKER))
            .with_context(|| self.tmp.join(MARKER).display().to_string())?;
        if self.target.exists() {
            std::fs::remove_dir_all(&self.target)
                .with_context(|| self.target.display().to_string())?;
        }
        std::fs::rename(&self.tmp, &self.target)
            .with_context(|| self.target.display().to_string())?;
        self.committed = true;
        link_latest(&self.target);
        Ok(self.target.clone())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.tmp);
        }
    }
}

/// Points `latest` beside the results folder at it (best effort: a missing link loses nothing).
pub fn link_latest(out: &Path) {
    let (Some(parent), Some(name)) = (out.parent(), out.file_name()) else {
        return;
    };
    let link = parent.join("latest");
    if link.is_symlink() {
        let _ = std::fs::remove_file(&link);
    }
    if !link.exists() {
        let _ = std::os::unix::fs::symlink(name, &link);
    }
}

/// Writes a file under a temporary name and renames it into place.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let tmp = path.with_file_name(format!(
        ".{}.tmp-{}",
        path.file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        std::process::id()
    ));
    let mut f = std::fs::File::create(&tmp).with_context(|| tmp.display().to_string())?;
    f.write_all(bytes)
        .and_then(|()| f.sync_all())
        .with_context(|| tmp.display().to_string())?;
    std::fs::rename(&tmp, path).with_context(|| path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_appears_whole_or_not_at_all_and_only_vinebench_folders_are_replaced() {
        let root = tempfile::tempdir().expect("temp dir");
        let target = root.path().join("bench");
        {
            let staging = Staging::begin(&target).expect("begin");
            std::fs::write(staging.dir().join("a"), "1").expect("write");
            // Dropped without commit: nothing appears, nothing is left.
        }
        assert!(!target.exists());
        assert_eq!(std::fs::read_dir(root.path()).expect("list").count(), 0);
        let staging = Staging::begin(&target).expect("begin");
        std::fs::write(staging.dir().join("a"), "2").expect("write");
        assert_eq!(staging.commit().expect("commit"), target);
        assert_eq!(std::fs::read_to_string(target.join("a")).expect("a"), "2");
        assert!(target.join(MARKER).exists());
        assert!(root.path().join("latest").is_symlink());
        // A rerun replaces its own folder; a foreign folder is refused, named.
        Staging::begin(&target)
            .expect("a vinebench folder")
            .commit()
            .expect("commit");
        assert!(!target.join("a").exists());
        let foreign = root.path().join("thesis");
        std::fs::create_dir(&foreign).expect("mkdir");
        std::fs::write(foreign.join("chapter.tex"), "x").expect("write");
        let err = Staging::begin(&foreign).expect_err("foreign").to_string();
        assert!(err.contains("thesis") && err.contains("not a vinebench results folder"));
    }

    /// A resumable folder is taken up again by the same fingerprint, replaced under another,
    /// kept when dropped, removed by `discard`, loses its partial marker when committed, and
    /// a foreign folder in its place is refused.
    #[test]
    fn a_partial_folder_resumes_only_the_same_plan() {
        let root = tempfile::tempdir().expect("temp dir");
        let target = root.path().join("bench");
        let partial = partial_path(&target);
        assert_eq!(partial, root.path().join(".bench.partial"));
        let (staging, resumed) = Staging::begin_resumable(&target, "plan-a").expect("begin");
        assert!(!resumed);
        std::fs::write(staging.dir().join("run"), "done").expect("write");
        drop(staging);
        assert!(partial.join("run").is_file(), "kept when dropped");
        let (staging, resumed) = Staging::begin_resumable(&target, "plan-a").expect("again");
        assert!(resumed);
        assert!(staging.dir().join("run").is_file());
        drop(staging);
        let (staging, resumed) = Staging::begin_resumable(&target, "plan-b").expect("other");
        assert!(!resumed);
        assert!(
            !staging.dir().join("run").exists(),
            "another plan starts afresh"
        );
        staging.discard().expect("discard");
        assert!(!partial.exists());
        let (staging, _) = Staging::begin_resumable(&target, "plan-c").expect("begin");
        std::fs::write(staging.dir().join("table.md"), "t").expect("write");
        assert_eq!(staging.commit().expect("commit"), target);
        assert!(target.join(MARKER).exists() && !target.join(PARTIAL).exists());
        assert!(!partial.exists());
        std::fs::create_dir(&partial).expect("mkdir");
        std::fs::write(partial.join("mine.txt"), "x").expect("write");
        let err = Staging::begin_resumable(&target, "plan-c")
            .expect_err("foreign")
            .to_string();
        assert!(err.contains("not a vinebench partial folder"), "{err}");
    }
}
