//! `sagnac report` on a multi-axis input without `--gyro` (a ROS 2 bag's six
//! axes, a triad capture, a recording of several gyros): each axis's own
//! report in `OUT/<label>/` (the accelerometer's in its units), side by side
//! on the cores, and `OUT/index.html` with every axis's coefficients and a
//! link to its page.

use std::path::Path;

use anyhow::{Context, Result};

use crate::input::Input;
use crate::pipeline::Analysis;
use crate::sink::report::Units;
use crate::sink::report::html::{AxisPage, index_page};

/// Write the axes' reports and the index.
pub(super) fn run(input: &Input, out: &Path, raw_statistics: bool) -> Result<()> {
    let labels = input.axes();
    let inputs = labels
        .iter()
        .map(|l| input.for_axis(l))
        .collect::<Result<Vec<_>, _>>()?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let results: Vec<Result<Analysis>> = std::thread::scope(|s| {
        let workers: Vec<_> = inputs
            .iter()
            .zip(&labels)
            .map(|(one, label)| {
                let dir = out.join(label);
                s.spawn(move || {
                    super::report_one::one(one, &dir, None, None, None, raw_statistics)
                        .map(|(_, a)| a)
                        .with_context(|| format!("the report of axis {label}"))
                })
            })
            .collect();
        workers
            .into_iter()
            .map(|w| w.join().expect("axis thread"))
            .collect()
    });
    let analyses = results.into_iter().collect::<Result<Vec<_>>>()?;
    let links: Vec<String> = labels.iter().map(|l| format!("{l}/index.html")).collect();
    let pages: Vec<AxisPage> = labels
        .iter()
        .zip(&inputs)
        .zip(&analyses)
        .zip(&links)
        .map(|(((label, one), analysis), link)| AxisPage {
            label,
            units: Units::of(one.meta().unit.quantity()),
            analysis,
            link,
        })
        .collect();
    let index = out.join("index.html");
    std::fs::write(
        &index,
        index_page(&input.path().display().to_string(), &pages),
    )
    .with_context(|| format!("writing {}", index.display()))?;
    super::write_stdout(&format!(
        "wrote {} and a report per axis in {}",
        index.display(),
        labels
            .iter()
            .map(|l| out.join(l).display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    ))
}
