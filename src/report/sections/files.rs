//! The files written beside the report.

use std::path::PathBuf;

use crate::report::{Report, Table};

/// The section "Files behind this report": each file's name and what it holds.
pub(crate) fn files(report: &mut Report, files: &[(PathBuf, String)]) {
    let mut t = Table::new(&["file", "what it holds"]).caption("Files next to this report");
    for (p, what) in files {
        let name = p.file_name().map_or_else(
            || p.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        t = t.row(vec![name.into(), what.clone().into()]);
    }
    report
        .section("Files behind this report")
        .paragraph(
            "Every number and figure above comes from these files; each can be re-read by \
             biasctl (logs by every command, models by predict and score).",
        )
        .table(t);
}
