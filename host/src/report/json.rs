//! `table.json`, shaped as DESIGN.md fixes it:
//! `{"<scenario>": {"<plugin>": {"status": "ok" | "failed: <reason>", "rmse": …,
//! "mean": …, "median": …, "max": …, "min": …, "std": …, "realtime_factor": …,
//! "loops_accepted": n, "loops_false": n}}}`.
//!
//! Scenarios and plugins appear in the table's column order. An ok run has every key,
//! with full f64 precision and `null` for a value that is missing or not finite;
//! `loops_accepted` counts the accepted loop closures, `loops_false` those of them that
//! ground truth shows false (a measured relative pose off by more than 0.5 m or 10°, or
//! without one, joining poses more than 1 m apart), and
//! `loops_unjudged`, present only when not zero, those that could not be judged (no
//! stamps). `wrong_joins` and `silent_joins` (the final map's wrong joins, and those no
//! accepted loop explains), `sim3_scale` and `drift_percent` follow when the run was
//! evaluated with them. A failed run has `status` only. A run whose route was cut (`--max-time`) also
//! has `max_time_s`, the route limit in simulated seconds, so a short-route table is never
//! mistaken for the paper's. A (scenario, plugin) pair without a run is absent.

use serde::Serialize;
use serde::ser::SerializeMap as _;

use super::table::{Column, Table};

/// One run's entry; untagged, so it serialises as its fields only. Made one column at a
/// time to be written at once: the size of its larger variant costs nothing.
#[derive(Serialize)]
#[serde(untagged)]
#[allow(clippy::large_enum_variant)]
enum Entry {
    Ok {
        status: &'static str,
        rmse: Option<f64>,
        mean: Option<f64>,
        median: Option<f64>,
        max: Option<f64>,
        min: Option<f64>,
        std: Option<f64>,
        realtime_factor: Option<f64>,
        loops_accepted: Option<usize>,
        loops_false: Option<usize>,
        #[serde(skip_serializing_if = "Option::is_none")]
        loops_unjudged: Option<usize>,
        #[serde(skip_serializing_if = "Option::is_none")]
        wrong_joins: Option<usize>,
        #[serde(skip_serializing_if = "Option::is_none")]
        silent_joins: Option<usize>,
        #[serde(skip_serializing_if = "Option::is_none")]
        sim3_scale: Option<f64>,
        #[serde(skip_serializing_if = "Option::is_none")]
        drift_percent: Option<f64>,
        #[serde(skip_serializing_if = "Option::is_none")]
        max_time_s: Option<f64>,
    },
    Failed {
        status: String,
        #[serde(skip_serializing_if = "Option::is_none")]
        max_time_s: Option<f64>,
    },
}

impl Entry {
    fn new(column: &Column) -> Self {
        if let Some(reason) = &column.failure {
            return Self::Failed {
                status: format!("failed: {reason}"),
                max_time_s: column.run.max_time_s,
            };
        }
        let ape = column.run.ape.as_ref();
        let stat = |field: fn(&eval::Statistics) -> f64| ape.map(field).filter(|v| v.is_finite());
        Self::Ok {
            status: "ok",
            rmse: stat(|s| s.rmse),
            mean: stat(|s| s.mean),
            median: stat(|s| s.median),
            max: stat(|s| s.max),
            min: stat(|s| s.min),
            std: stat(|s| s.std),
            realtime_factor: column.run.realtime_factor.filter(|v| v.is_finite()),
            loops_accepted: column.run.loops.map(|l| l.accepted),
            loops_false: column.run.loops.map(|l| l.accepted_false),
            loops_unjudged: column.run.loops.map(|l| l.unjudged).filter(|&n| n > 0),
            wrong_joins: column.run.joins.map(|j| j.wrong_joins),
            silent_joins: column.run.joins.map(|j| j.silent),
            sim3_scale: column.run.sim3_scale.filter(|v| v.is_finite()),
            drift_percent: column.run.drift_percent.filter(|v| v.is_finite()),
            max_time_s: column.run.max_time_s,
        }
    }
}

/// The whole table as a map in column order (serde_json's own `Map` would sort keys).
struct Report<'t, 'a>(&'t Table<'a>);

/// The runs of one scenario as a map in plugin order.
struct ScenarioRuns<'t, 'a>(Vec<&'t Column<'a>>);

impl Serialize for Report<'_, '_> {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let groups = self.0.groups();
        let mut map = serializer.serialize_map(Some(groups.len()))?;
        for (scenario, range) in groups {
            map.serialize_entry(
                scenario,
                &ScenarioRuns(self.0.columns[range].iter().collect()),
            )?;
        }
        map.end()
    }
}

impl Serialize for ScenarioRuns<'_, '_> {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(self.0.len()))?;
        for column in &self.0 {
            map.serialize_entry(&column.run.plugin, &Entry::new(column))?;
        }
        map.end()
    }
}

/// The pretty-printed JSON of `table`, ending with a newline.
pub(super) fn render(table: &Table) -> anyhow::Result<String> {
    let mut json = serde_json::to_string_pretty(&Report(table))?;
    json.push('\n');
    Ok(json)
}
