//! A user's log: what it holds and the views that fit it (bias vs position always; one track
//! over time and bias vs seek length only when the positions are seeks to tracks).

use crate::plot::from_log;
use crate::plot::svg::fmt_num;
use crate::report::run::DataRun;
use crate::report::{Cell, Report, Table};

/// The section "Your data": rows, columns, units, covariates, ranges and the data views.
pub(crate) fn your_data(r: &mut Report, run: &DataRun) {
    let log = &run.log;
    let units = &log.schema.units;
    let tracks: Vec<f64> = log.rows().map(|x| x.track).collect();
    let [lo, hi] = crate::numeric::stats::range(&tracks).unwrap_or([f64::NAN; 2]);
    let sec = r.section("Your data");
    sec.table(
        Table::new(&["quantity", "value"])
            .row(vec!["rows".into(), log.len().into()])
            .row(vec!["measured rows".into(), log.measured_count().into()])
            .row(vec![
                "columns (time, position, bias)".into(),
                format!(
                    "{}, {}, {}",
                    log.schema.map.time, log.schema.map.track, log.schema.map.bias
                )
                .into(),
            ])
            .row(vec![
                "units (bias, position)".into(),
                format!("{}, {}", units.bias, units.position).into(),
            ])
            .row(vec![
                "covariates".into(),
                log.schema.covariates.join(", ").into(),
            ])
            .row(vec![
                "position range".into(),
                format!("{} … {} {}", fmt_num(lo), fmt_num(hi), units.position).into(),
            ])
            .row(vec![
                "time span (s)".into(),
                Cell::Number(
                    log.last().map_or(0.0, |x| x.time_s) - log.first().map_or(0.0, |x| x.time_s),
                ),
            ]),
    )
    .figure(
        from_log::bias_vs_position(log),
        "Bias vs position, split by the direction of the move into each row (Fig. 3 view).",
    );
    if run.tracks_like {
        sec.figure(
            from_log::bias_vs_time(log, None),
            "Bias vs time at the position measured most often (Fig. 4 view).",
        )
        .figure(
            from_log::bias_vs_seek_length(log),
            "Bias vs signed seek length, split by whether the seek reversed direction \
                 (Figs. 5–9 view).",
        );
    } else {
        sec.paragraph(
            "The views of one track over time (Fig. 4) and of bias against seek length \
             (Figs. 5–9) are left out: this log's positions form a continuous trajectory, not \
             repeated visits to a set of tracks.",
        );
    }
}
