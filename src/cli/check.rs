//! `biasctl check`: validate a log and summarise it.

use super::common::LogArgs;
use biasctl::log::LogReader;

/// Flags of `biasctl check`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    log: LogArgs,
}

/// Streams the log and prints rows, measured rows, span, units, the sampling (rows/s, how the
/// direction of motion is read, reversals, the position-noise estimate) and covariates.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut reader = LogReader::open(&args.log.data, &args.log.columns.map())?;
    let units = args.log.columns.units(reader.schema())?;
    let sum = reader.summarise()?;
    let s = reader.schema();
    println!("{}: {} rows, {} measured", s.file, sum.rows, sum.measured);
    println!(
        "  positions {} .. {} {} (column {})",
        sum.positions[0], sum.positions[1], units.position, s.map.track
    );
    println!("  bias in {} (column {})", units.bias, s.map.bias);
    println!(
        "  time {} .. {} s (column {})",
        sum.times_s[0], sum.times_s[1], s.map.time
    );
    let log = args.log.columns.read_log(&args.log.data)?;
    let times: Vec<f64> = log.rows.iter().map(|r| r.time_s).collect();
    let positions: Vec<f64> = log.rows.iter().map(|r| r.track).collect();
    for line in biasctl::history::sampling(&times, &positions).describe(&units.position) {
        println!("  {line}");
    }
    if !s.covariates.is_empty() {
        println!("  covariates: {}", s.covariates.join(", "));
    }
    for m in &s.metadata {
        println!("  # {m}");
    }
    Ok(())
}
