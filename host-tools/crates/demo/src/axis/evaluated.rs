//! A campaign read back through the CLI's reader and evaluated by ISO 230-2.

use axcomp_data::{Dataset, LoadOptions};
use axcomp_positioning::iso230::{self, Iso230Result};
use axcomp_twin::Campaign;

use crate::{Result, StepContext};

/// One evaluated campaign.
pub(super) struct Evaluated {
    pub campaign: Campaign,
    pub data: Dataset,
    pub iso: Iso230Result,
    pub rms_um: f64,
}

pub(super) fn evaluate(name: &str, campaign: Campaign) -> Result<Evaluated> {
    let csv = campaign.to_csv_string();
    // Through the same reader the CLI uses for user files.
    let data = Dataset::from_csv_str(name, &csv, &LoadOptions::default())?;
    let points = iso230::points_from_dataset(&data, "deviation_um")?;
    let iso = iso230::evaluate(&points).step(|| format!("ISO 230-2 evaluation of {name}"))?;
    let dev = data.numeric("deviation_um")?;
    let rms_um = (dev.iter().map(|d| d * d).sum::<f64>() / dev.len() as f64).sqrt();
    Ok(Evaluated {
        campaign,
        data,
        iso,
        rms_um,
    })
}
