//! `biasctl check`: validate a log and summarise it.

use super::common::LogArgs;
use biasctl::log::{LogReader, Row};

/// Flags of `biasctl check`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    log: LogArgs,
}

/// Streams the log once and prints rows, measured rows, span, units and covariates.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut reader = LogReader::open(&args.log.data, &args.log.columns.map())?;
    let units = args.log.columns.units(reader.schema())?;
    let mut row = Row {
        line: 0,
        time_s: 0.0,
        track: 0.0,
        bias: None,
        covariates: Vec::new(),
    };
    let (mut n, mut measured) = (0u64, 0u64);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut t0, mut t1) = (0.0, 0.0);
    while reader.read_into(&mut row)? {
        if n == 0 {
            t0 = row.time_s;
        }
        t1 = row.time_s;
        n += 1;
        measured += u64::from(row.bias.is_some());
        lo = lo.min(row.track);
        hi = hi.max(row.track);
    }
    let s = reader.schema();
    println!("{}: {n} rows, {measured} measured", s.file);
    println!(
        "  positions {lo} .. {hi} {} (column {})",
        units.position, s.map.track
    );
    println!("  bias in {} (column {})", units.bias, s.map.bias);
    println!("  time {t0} .. {t1} s (column {})", s.map.time);
    if !s.covariates.is_empty() {
        println!("  covariates: {}", s.covariates.join(", "));
    }
    for m in &s.metadata {
        println!("  # {m}");
    }
    Ok(())
}
