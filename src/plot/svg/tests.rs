//! Ticks, number text, escaping and clipping.

use super::axes::{nice_step, nice_ticks, tick_labels};
use super::marks::clip;
use super::*;

#[test]
fn nice_steps_are_1_2_5() {
    assert!((nice_step(10.0, 5) - 2.0).abs() < 1e-12);
    assert!((nice_step(100.0, 5) - 20.0).abs() < 1e-12);
    assert!((nice_step(0.7, 5) - 0.1).abs() < 1e-12);
    assert!((nice_step(37.0, 5) - 5.0).abs() < 1e-12);
    assert!((nice_step(0.0, 5) - 1.0).abs() < 1e-12);
    let t = nice_ticks(-3.2, 17.9, 5);
    let want = [0.0, 5.0, 10.0, 15.0];
    assert_eq!(t.len(), want.len(), "{t:?}");
    for (a, b) in t.iter().zip(want) {
        assert!((a - b).abs() < 1e-12);
    }
}

#[test]
fn tick_labels_have_no_float_noise() {
    let t = tick_labels(0.0, 0.7, 7);
    let labels: Vec<&str> = t.iter().map(|(_, s)| s.as_str()).collect();
    assert_eq!(
        labels,
        ["0", "0.1", "0.2", "0.3", "0.4", "0.5", "0.6", "0.7"]
    );
}

#[test]
fn numbers_are_compact() {
    assert_eq!(fmt_num(0.0), "0");
    assert_eq!(fmt_num(7.94321), "7.943");
    assert_eq!(fmt_num(-19.0), "-19");
    assert_eq!(fmt_num(1234.5678), "1235");
    assert_eq!(fmt_num(2.5e6), "2.5e6");
    assert_eq!(fmt_num(1.0e-4), "1e-4");
    assert_eq!(fmt_num(f64::NAN), "n/a");
    assert_eq!(fmt_num(f64::NEG_INFINITY), "n/a");
}

#[test]
fn escaping_covers_markup() {
    assert_eq!(
        esc(r#"a<b & "c" 'd'>"#),
        "a&lt;b &amp; &quot;c&quot; &#39;d&#39;&gt;"
    );
}

#[test]
fn clipping_cuts_segments_at_the_range() {
    let lay = Chart::new("").line("", &[(0.0, 0.0), (1.0, 1.0)]).layout();
    let (a, b) = clip(&lay, (-1.0, 0.5), (2.0, 0.5)).unwrap();
    // The automatic range is padded: the segment is cut at the padded ends.
    assert!((a.0 - lay.x_lo).abs() < 1e-12 && (b.0 - lay.x_hi).abs() < 1e-12);
    assert!((lay.x_lo + AXIS_PADDING).abs() < 1e-12);
    assert!(clip(&lay, (-1.0, 2.0), (2.0, 2.0)).is_none());
}

/// Reference: where the data lie, by construction. A reference line's label goes where it
/// covers no data: at the right end when the data are away from it there, else at the left.
#[test]
fn a_reference_label_avoids_the_data() {
    let label_anchor = |pts: &[(f64, f64)]| {
        let svg = Chart::new("t").line("d", pts).hline(5.0, "level").to_svg();
        let at = svg.find(">level</text>").expect("label drawn");
        let start = svg[..at].rfind("<text").unwrap();
        svg[start..at].contains(r#"text-anchor="start""#)
    };
    // Data crossing the line's level over the right third, far from it on the left.
    let right: Vec<(f64, f64)> = (0..=100)
        .map(|i| {
            let x = f64::from(i);
            (x, if i > 66 { 5.0 + (x * 0.7).sin() } else { -5.0 })
        })
        .collect();
    assert!(
        label_anchor(&right),
        "label left at the right end, over the data"
    );
    // Mirrored: the right end is free, the label stays there.
    let left: Vec<(f64, f64)> = right.iter().map(|&(x, y)| (100.0 - x, y)).collect();
    assert!(!label_anchor(&left));
}
