//! What bias is: the paper's phenomena P1–P8, the simulated Tables I–VII drawn as Figs. 3–9
//! and 12, and the simulator's true decomposition of the bias (Table A). The built-in drive
//! only: a user's log has no tables and no truth.

use crate::log::Log;
use crate::plot::figures::{Sweep, SweepFigure, SweepSeries, calibration_sweep};
use crate::plot::from_log;
use crate::report::run::DemoRun;
use crate::report::{Cell, Report, Table};
use crate::sim::Truth;

/// The section "What bias is, and what this drive shows" of the demo.
pub(crate) fn what_bias_is(r: &mut Report, run: &DemoRun) {
    let s = r.section("What bias is, and what this drive shows");
    s.paragraph(
            "Bias is the average current the voice-coil driver must supply to hold the head on \
             a track, measured as the tracking controller's integrator averaged over one disk \
             revolution once the head has settled. Units are counts (DAC counts of the driver). \
             Tracks are numbered from the outer diameter (OD, track 0) inwards; a positive seek \
             moves inbound, towards the inner diameter (ID). If the firmware knew the bias \
             before the head arrives it could start the integrator there and settle faster.",
        )
        .table(
            Table::new(&["#", "effect", "what the data show"])
                .caption("The bias phenomena of the paper (Section II)")
                .row(vec!["P1".into(), "position".into(), "a smooth trend over the stroke, a 2nd-order polynomial (Fig. 3)".into()])
                .row(vec!["P2".into(), "direction".into(), "inbound and outbound curves offset by a constant — pivot hysteresis (Fig. 3)".into()])
                .row(vec!["P3".into(), "time at track".into(), "at one track the bias creeps to a constant over seconds (Fig. 4)".into()])
                .row(vec!["P4".into(), "seek length".into(), "after a reversal short seeks trace a loop; ~50–100 tracks overshoot, ~100–200 undershoot (Figs. 5, 6)".into()])
                .row(vec!["P5".into(), "direction change at source".into(), "the overshoot is weaker without a reversal at the source (Figs. 7, 8)".into()])
                .row(vec!["P6".into(), "rest-position memory".into(), "an earlier rest close to the target, not crossed since, changes the bias (Fig. 9)".into()])
                .row(vec!["P7".into(), "drift".into(), "the constant term wanders over minutes (driver offset)".into()])
                .row(vec!["P8".into(), "scatter".into(), "measurement noise: turbulence, head/disk contact".into()]),
        )
        .figure(
            from_log::bias_vs_position(&run.tables[0]),
            "Fig. 3 (Table I, P1+P2): each target approached from far OD (inbound) and from far \
             ID (outbound). Two curves of the same shape; the gap between them is twice the \
             pivot's friction level.",
        )
        .figure(
            from_log::bias_vs_time(&run.dwell, None),
            "Fig. 4 (P3): the head stays on one track for 10 s; the bias approaches a constant.",
        );
    for (svg, caption) in table_sweeps(&run.tables) {
        s.figure(svg, caption);
    }
    s.table(truth_table(&run.truth)).paragraph(
        "Table A is only possible on a simulator: it splits each measured bias of the random \
             test run into its causes. Position and direction are most of the variation; the \
             seek-length and memory effects are what the simple model below leaves behind.",
    );
}

/// `(x, bias)` of the measured rows of a table log with their history features, and the
/// previous rows' tracks (for the rest offset of Table VI).
fn measured_rows(log: &Log) -> Vec<Measured> {
    let mut out = Vec::new();
    for (i, r, f) in crate::history::replay(log) {
        let two_back = i.checked_sub(2).map(|j| log.row(j).track);
        if let Some(b) = r.bias {
            out.push((f, b, two_back));
        }
    }
    out
}

/// The Figs. 5–9 and 12 sweeps of the simulated Tables II–VII (see
/// [`crate::sim::sequence::table`] for the sequences).
fn table_sweeps(tables: &[Log]) -> Vec<(String, String)> {
    let rows: Vec<_> = tables.iter().map(measured_rows).collect();
    let mut out = Vec::new();
    // Fig. 5: the Table II loop.
    let t2 = &rows[1];
    let branch = |dir: i8| -> Vec<(f64, f64)> {
        t2.iter()
            .skip(1)
            .filter(|(f, _, _)| f.direction == dir)
            .map(|(f, b, _)| (f.target, *b))
            .collect()
    };
    let mut loop_sweep = Sweep {
        figure: SweepFigure::Fig5SeekLength,
        series: vec![
            series("outbound one-track steps", branch(-1), true),
            series("inbound one-track steps back", branch(1), true),
        ],
        levels: refs(t2, 1),
    };
    let svg5 = calibration_sweep(&loop_sweep)
        .replace("tracks moved since reversal (tracks)", "position (tracks)")
        .replace(
            "bias vs tracks moved since reversal",
            "the Table II loop, bias vs position",
        );
    out.push((
        svg5,
        "Fig. 5 (Table II, P4): after a long inbound seek the head steps outbound one track at a \
         time, then back. The bias does not jump to the outbound curve: it walks along a \
         hysteresis loop between the two curves — the pivot's friction needs tens of tracks of \
         travel to reverse."
            .into(),
    ));
    loop_sweep.levels.clear();
    // Fig. 6: Table III.
    let t3 = &rows[2];
    let pts3: Vec<(f64, f64)> = t3
        .iter()
        .skip(2)
        .map(|(f, b, _)| (-f.seek_length, *b))
        .collect();
    out.push((
        calibration_sweep(&Sweep {
            figure: SweepFigure::Fig6SourceOffset,
            series: vec![series("direction change at source", pts3, true)],
            levels: refs(t3, 2),
        }),
        "Fig. 6 (Table III, P4): bias at one target after a seek from a source at the given \
         offset, always reversing at the source. Short seeks stay between the curves, seeks of \
         ~50–100 tracks overshoot the far curve, ~100–200 undershoot it, longer ones land on it."
            .into(),
    ));
    // Figs. 7 and 8: Tables IV and V.
    for (k, fig, caption) in [
        (
            3usize,
            SweepFigure::Fig7NoDirectionChange,
            "Fig. 7 (Table IV, P5): the same sweep without a direction change at the source: \
             the overshoot is weaker.",
        ),
        (
            4usize,
            SweepFigure::Fig8DirectionChange,
            "Fig. 8 (Table V, P5): with a direction change at the source (the head crossed the \
             source first): the overshoot is stronger.",
        ),
    ] {
        let t = &rows[k];
        let side = |inbound: bool| -> Vec<(f64, f64)> {
            t.iter()
                .skip(2)
                .filter(|(f, _, _)| (f.seek_length > 0.0) == inbound)
                .map(|(f, b, _)| (-f.seek_length, *b))
                .collect()
        };
        out.push((
            calibration_sweep(&Sweep {
                figure: fig,
                series: vec![
                    series("inbound seeks (source on OD side)", side(true), true),
                    series("outbound seeks (source on ID side)", side(false), true),
                ],
                levels: refs(t, 2),
            }),
            caption.into(),
        ));
    }
    out.push(fig9_rest_offset(&rows[5]));
    out.push(fig12_seek_count(t2, &rows[6]));
    out
}

/// A measured row of a table log: its history features, its bias and the track two rows back.
type Measured = (crate::history::SeekFeatures, f64, Option<f64>);

/// One series of a sweep figure.
fn series(name: &str, points: Vec<(f64, f64)>, joined: bool) -> SweepSeries {
    SweepSeries {
        name: name.into(),
        points,
        joined,
    }
}

/// The first `n` rows' biases as reference levels, labelled by the curve they lie on.
fn refs(t: &[Measured], n: usize) -> Vec<(String, f64)> {
    t.iter()
        .take(n)
        .map(|(f, b, _)| {
            let label = if f.direction > 0 {
                "inbound curve at target"
            } else {
                "outbound curve at target"
            };
            (label.to_string(), *b)
        })
        .collect::<Vec<_>>()
}

/// Fig. 9 from Table VI's rows, with its caption.
fn fig9_rest_offset(t6: &[Measured]) -> (String, String) {
    let pts6: Vec<(f64, f64)> = t6
        .iter()
        .skip(1)
        .filter_map(|(f, b, p)| p.map(|p| (p - f.target, *b)))
        .collect();
    (
        calibration_sweep(&Sweep {
            figure: SweepFigure::Fig9RestOffset,
            series: vec![series("rest at offset, far OD, then target", pts6, true)],
            levels: vec![(
                "no rest nearby".into(),
                t6.first().map_or(f64::NAN, |r| r.1),
            )],
        }),
        "Fig. 9 (Table VI, P6): the head rested at an intermediate position, went far OD, then \
         came to the target. A rest position close to the target on one side, not crossed since, \
         changes the bias there: the pivot remembers where it rested."
            .into(),
    )
}

/// Fig. 12 from Table VII's rows against the Table II branch, with its caption.
fn fig12_seek_count(t2: &[Measured], t7: &[Measured]) -> (String, String) {
    let one: Vec<(f64, f64)> = t7
        .iter()
        .map(|(f, b, _)| (f.seek_length.abs(), *b))
        .collect();
    let start = t2.first().map_or(0.0, |r| r.0.target);
    let many: Vec<(f64, f64)> = t2
        .iter()
        .skip(1)
        .filter(|(f, _, _)| f.direction < 0)
        .map(|(f, b, _)| (start - f.target, *b))
        .collect();
    (
        calibration_sweep(&Sweep {
            figure: SweepFigure::Fig12SeekCount,
            series: vec![
                series("one N-track seek (Table VII)", one, true),
                series("N one-track seeks (Table II)", many, true),
            ],
            levels: Vec::new(),
        }),
        "Fig. 12 (Table VII): after a direction change, one seek of N tracks against N one-track \
         seeks. They differ: seek length matters, not only the distance travelled — which is \
         why the Dahl model, which treats an N-track seek as N one-track seeks, misses the \
         overshoot."
            .into(),
    )
}

/// Std of each true effect over the measured rows.
fn truth_table(truth: &[Truth]) -> Table {
    type Get = fn(&Truth) -> f64;
    let effects: [(&str, &str, Get); 9] = [
        ("P1 position", "flex cable, windage, gravity", |t| {
            t.position
        }),
        ("P2 direction", "pivot friction, main element", |t| {
            t.direction
        }),
        ("P4/P5 seek length", "pivot friction, extra elements", |t| {
            t.overshoot
        }),
        ("P3 time at track", "lubricant flow", |t| t.time),
        ("P6 rest memory", "pivot rest positions", |t| t.memory),
        ("P7 drift", "driver electronics", |t| t.drift),
        ("temperature", "ambient covariate", |t| t.temperature),
        ("P8 scatter", "turbulence, head/disk contact", |t| t.scatter),
        ("runout residue", "one-revolution average", |t| t.runout),
    ];
    let mut table = Table::new(&["effect", "source", "std (counts)", "range (counts)"]).caption(
        "Table A. The simulator's true decomposition of the bias over the random test run",
    );
    for (name, source, get) in effects {
        let v: Vec<f64> = truth.iter().map(get).collect();
        let spread = crate::numeric::stats::range(&v).map_or(f64::NAN, |[lo, hi]| hi - lo);
        table = table.row(vec![
            name.into(),
            source.into(),
            Cell::Fixed(crate::numeric::stats::std_dev(&v).unwrap_or(f64::NAN), 2),
            Cell::Fixed(spread, 2),
        ]);
    }
    table
}
