//! Published figures a bench reproduces, shown beside ours: a bench file's `paper_table`
//! (configs/paper.toml: Hroob et al. 2021's Table 2, `configs/hroob2021-table2.csv`). The
//! runner copies the file into the results folder as [`FILE`], so the report rebuilt from
//! the folder alone shows them too. Every table gets rows `paper max` .. `paper std` with
//! the published value of each column's (scenario, system), blank where the paper has none.

use std::path::Path;

use anyhow::{Context as _, bail};

/// The reference's name in a results folder.
pub const FILE: &str = "paper.csv";

/// The statistics a reference gives, in its columns' order (the paper's Table 2).
pub const STATISTICS: [&str; 5] = ["max", "mean", "median", "rmse", "std"];

/// One published (scenario, system): its [`STATISTICS`] in metres.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceEntry {
    pub scenario: String,
    pub system: String,
    pub values: [f64; 5],
}

/// A published table: `scenario,system,max,mean,median,rmse,std` rows after a header of
/// those names; lines starting with `#` are comments (its source).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Reference {
    pub entries: Vec<ReferenceEntry>,
}

impl Reference {
    /// Parses the CSV text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> anyhow::Result<Self> {
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty() && !l.starts_with('#'));
        let header: Vec<&str> = match lines.next() {
            Some((_, l)) => l.split(',').map(str::trim).collect(),
            None => bail!("{origin}: no header line"),
        };
        let expected: Vec<&str> = ["scenario", "system"]
            .into_iter()
            .chain(STATISTICS)
            .collect();
        if header != expected {
            bail!("{origin}: header must be {}", expected.join(","));
        }
        let mut entries = Vec::new();
        for (i, line) in lines {
            let cells: Vec<&str> = line.split(',').map(str::trim).collect();
            if cells.len() != expected.len() {
                bail!(
                    "{origin} line {}: {} fields, expected {}",
                    i + 1,
                    cells.len(),
                    expected.len()
                );
            }
            let mut values = [0.0; 5];
            for (v, text) in values.iter_mut().zip(&cells[2..]) {
                *v = text
                    .parse()
                    .ok()
                    .filter(|v: &f64| v.is_finite())
                    .with_context(|| {
                        format!("{origin} line {}: {text:?} is not a number", i + 1)
                    })?;
            }
            entries.push(ReferenceEntry {
                scenario: cells[0].to_owned(),
                system: cells[1].to_owned(),
                values,
            });
        }
        Ok(Self { entries })
    }

    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read the paper's table", path.display()))?;
        Self::parse(&text, &path.display().to_string())
    }

    /// The reference of a results folder, if it has one.
    pub fn in_folder(dir: &Path) -> anyhow::Result<Option<Self>> {
        let path = dir.join(FILE);
        path.exists().then(|| Self::load(&path)).transpose()
    }

    /// The published statistics of `system` on `scenario`.
    pub fn get(&self, scenario: &str, system: &str) -> Option<&[f64; 5]> {
        self.entries
            .iter()
            .find(|e| e.scenario == scenario && e.system == system)
            .map(|e| &e.values)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_papers_table_parses_and_bad_lines_are_named() {
        let text = include_str!("../../../configs/hroob2021-table2.csv");
        let r = Reference::parse(text, "table2.csv").expect("parses");
        assert_eq!(r.entries.len(), 16, "four systems on four scenarios");
        assert_eq!(
            r.get("s3", "orbslam2"),
            Some(&[8.95, 4.35, 3.91, 5.22, 2.90])
        );
        assert_eq!(r.get("s3", "wheel-odometry"), None);
        let e = Reference::parse("scenario,system,max\n", "t.csv").expect_err("header");
        assert!(e.to_string().contains("t.csv: header"), "{e}");
        let e = Reference::parse(
            "scenario,system,max,mean,median,rmse,std\ns0,x,1,2,oops,4,5\n",
            "t.csv",
        )
        .expect_err("value");
        assert!(e.to_string().contains("t.csv line 2: \"oops\""), "{e}");
    }
}
