//! One knob's sweep: each setting's time and error against a named
//! reference, the Pareto front over them, and why the default sits where
//! it does.

/// One setting of a knob, measured.
#[derive(Debug, Clone)]
pub struct Row {
    /// The setting as a user writes it (`"bilinear"`, `"n 127, L 8"`).
    pub setting: String,
    /// The cost, in the sweep's time unit (see `Sweep::time`).
    pub time: f64,
    /// The error, in the sweep's measure (see `Sweep::error`).
    pub error: f64,
    /// The setting relief uses when the manifest says nothing.
    pub default: bool,
    /// More columns for the table: (header, value), the same headers in
    /// every row of a sweep.
    pub extra: Vec<(String, String)>,
}

impl Row {
    pub fn new(setting: impl Into<String>, time: f64, error: f64) -> Self {
        Self { setting: setting.into(), time, error, default: false, extra: Vec::new() }
    }

    #[must_use]
    pub fn default_if(mut self, is_default: bool) -> Self {
        self.default = is_default;
        self
    }

    #[must_use]
    pub fn with(mut self, header: impl Into<String>, value: impl Into<String>) -> Self {
        self.extra.push((header.into(), value.into()));
        self
    }
}

/// A knob swept against a reference.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// The knob's name as the manifest or the source options spell it
    /// (`resampling`, `clipmap_grid_size and clipmap_levels`); also the
    /// plot's file name once made safe.
    pub knob: String,
    /// What was measured, on what data, in a sentence.
    pub case: String,
    /// The independent reference the error is measured against.
    pub reference: String,
    /// The error measure and its unit (`RMS height error, m`).
    pub error: String,
    /// The time measure and its unit (`ms per tile, median of 5`).
    pub time: String,
    pub rows: Vec<Row>,
    /// Why the default is where it is, in the light of these numbers.
    pub why_default: String,
}

impl Sweep {
    /// Indices of the rows on the Pareto front: no other row is at least as
    /// fast and as accurate, and strictly better in one.
    pub fn pareto(&self) -> Vec<usize> {
        let dominated = |i: usize| {
            let a = &self.rows[i];
            self.rows.iter().enumerate().any(|(j, b)| {
                j != i && b.time <= a.time && b.error <= a.error && (b.time < a.time || b.error < a.error)
            })
        };
        let mut front: Vec<usize> = (0..self.rows.len()).filter(|&i| !dominated(i)).collect();
        front.sort_by(|&a, &b| self.rows[a].time.total_cmp(&self.rows[b].time));
        front
    }

    /// Where the default stands, measured: on the front, or which settings
    /// beat it on both counts (a sentence for the report).
    pub fn default_standing(&self) -> String {
        let Some(d) = self.rows.iter().position(|r| r.default) else {
            return "No default was measured in this sweep.".into();
        };
        let def = &self.rows[d];
        let better: Vec<&Row> = self
            .rows
            .iter()
            .filter(|r| r.time <= def.time && r.error <= def.error && (r.time < def.time || r.error < def.error))
            .collect();
        if better.is_empty() {
            return format!("Measured: the default ({}) is on the Pareto front.", def.setting);
        }
        let named: Vec<String> = better
            .iter()
            .map(|r| {
                format!(
                    "{} ({} against {}, error {} against {})",
                    r.setting,
                    crate::report::number(r.time),
                    crate::report::number(def.time),
                    crate::report::number(r.error),
                    crate::report::number(def.error)
                )
            })
            .collect();
        format!(
            "Measured: the default ({}) is not on this case's front; at least as fast and as accurate here: {}.",
            def.setting,
            named.join("; ")
        )
    }

    /// The plot's file name: the knob's name with anything but letters,
    /// digits and underscores made underscores.
    pub fn file_stem(&self) -> String {
        self.knob.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' { c } else { '_' }).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_front_keeps_rows_nothing_beats_on_both_counts() {
        let sweep = Sweep {
            knob: "k".into(),
            case: String::new(),
            reference: String::new(),
            error: String::new(),
            time: String::new(),
            rows: vec![
                Row::new("slow exact", 10.0, 0.0),
                Row::new("fast rough", 1.0, 5.0),
                Row::new("dominated", 11.0, 1.0),
                Row::new("middle", 4.0, 2.0),
                Row::new("tie in time, worse", 4.0, 3.0),
            ],
            why_default: String::new(),
        };
        assert_eq!(sweep.pareto(), vec![1, 3, 0]);
    }
}
