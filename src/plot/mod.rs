//! Plots: hand-written SVG charts (`svg`, its builder [`Chart`] re-exported here), one builder
//! per paper figure ([`figures`]), and quick-look plots of a measurement log with no model
//! ([`from_log`]), and figures of library results — fitted models, diagnoses, ladders, settle
//! analyses ([`views`]).
//!
//! Public as a namespace (`biasctl::plot`) because a user needs it as one: a figure is picked by
//! its builder's name (`views::ladder`, `from_log::bias_vs_time`, …), names that would be
//! ambiguous at the top of the crate, and a user drawing their own chart in the report's style
//! uses [`Chart`].
//!
//! Every builder takes plain data and returns SVG text; nothing here reads files or depends on
//! the simulator, and only [`views`] knows the model, diagnose and settle types. Write the text with [`crate::io::write_string_atomic`] or put
//! it into a `crate::report::Report`.

pub mod figures;
pub mod from_log;
pub(crate) mod svg;
pub mod views;

pub use svg::{
    AXIS_PADDING, AxisRange, Chart, ErrorPoint, Layout, PALETTE, Panel, Reference, SCATTER_CELL_PX,
    Series, SeriesData, fmt_num,
};
