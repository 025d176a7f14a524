//! `glint check`'s output: per device, what glint chose for it and a table
//! of the cases; and the same verdicts as JUnit XML, which every CI system
//! reads.

use std::fmt::Write as _;

use quick_junit::{NonSuccessKind, Report, TestCase, TestCaseStatus, TestSuite};

use super::{CaseResult, DeviceReport};
use crate::units::human;

/// What a bug report about the device needs: the device, its driver, the
/// limits glint planned against and the profile it chose.
pub fn header(report: &DeviceReport) -> String {
    let d = &report.device;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "device {}: {} ({}, Vulkan {}, {})",
        d.index, d.name, d.device_type, d.api_version, d.driver
    );
    if let Some(l) = &report.limits {
        let _ = writeln!(
            out,
            "  limits: storage binding {}, uniform binding {}, allocation {}, {} storage and {} uniform buffers a stage, subgroup {}, timestamps {}",
            human(l.max_storage_range),
            human(l.max_uniform_range),
            human(l.max_allocation),
            l.max_storage_buffers,
            l.max_uniform_buffers,
            l.subgroup_size,
            if l.timestamp_bits > 0 { "yes" } else { "no" }
        );
    }
    let decisions: Vec<String> = d
        .profile
        .decisions()
        .iter()
        .map(|(what, value)| format!("{what} {value}"))
        .collect();
    let _ = writeln!(
        out,
        "  profile: {}: {}",
        d.profile.kind,
        decisions.join(", ")
    );
    out
}

/// One line of the table.
pub fn row(c: &CaseResult) -> String {
    let rays = c
        .rays_per_second
        .map_or("-".into(), |r| format!("{:.1} M/s", r / 1e6));
    let allowed = if c.allowed == usize::MAX {
        "-".to_string()
    } else {
        c.allowed.to_string()
    };
    format!(
        "{:<28} {:>5}/{:<5} {:>6.0} {:>9.5} {:>9.5} {:>10.1} {:>12}  {}  {} [{}]",
        c.name,
        c.off,
        allowed,
        c.worst,
        c.flip_f32,
        c.flip_f64,
        c.time.as_secs_f64() * 1e3,
        rays,
        if c.passed() { "PASS" } else { "FAIL" },
        c.exercises,
        c.variant
    )
}

/// The table's head.
pub fn columns() -> String {
    format!(
        "{:<28} {:>11} {:>6} {:>9} {:>9} {:>10} {:>12}  verdict  exercises [shader variant]",
        "scene", "off/allowed", "worst", "FLIP f32", "FLIP f64", "ms", "rays"
    )
}

/// The verdict lines after the table: each failure, why.
pub fn verdict(report: &DeviceReport) -> String {
    let failed: Vec<&CaseResult> = report.cases.iter().filter(|c| !c.passed()).collect();
    let (compiled, from_disk) = report.pipelines;
    let pipelines = format!("{compiled} pipelines compiled, {from_disk} from the disk cache");
    if failed.is_empty() {
        return format!(
            "PASS: {} of {} scenes on device {} ({:.1} s; {pipelines})\n",
            report.cases.len(),
            report.cases.len(),
            report.device.index,
            report.total.as_secs_f64()
        );
    }
    let mut out = format!(
        "FAIL: {} of {} scenes on device {}:\n",
        failed.len(),
        report.cases.len(),
        report.device.index
    );
    for c in failed {
        let _ = writeln!(out, "  {}: {}", c.name, c.failure.as_deref().unwrap_or(""));
    }
    out
}

/// JUnit XML: a test suite per device, a test case per scene.
pub fn junit(reports: &[DeviceReport]) -> String {
    let mut report = Report::new("glint check");
    for r in reports {
        let d = &r.device;
        let mut suite = TestSuite::new(format!("device {}: {}", d.index, d.name));
        suite.set_time(r.total);
        suite.set_system_out(header(r));
        for c in &r.cases {
            let status = match &c.failure {
                None => TestCaseStatus::success(),
                Some(why) => {
                    let mut s = TestCaseStatus::non_success(NonSuccessKind::Failure);
                    s.set_message(why.clone());
                    s.set_type("image mismatch");
                    s
                }
            };
            let mut case = TestCase::new(c.name.clone(), status);
            case.set_classname(format!("glint.check.{}", d.name));
            case.set_time(c.time);
            case.set_system_out(row(c));
            suite.add_test_case(case);
        }
        report.add_test_suite(suite);
    }
    report
        .to_string()
        .unwrap_or_else(|e| format!("<!-- JUnit serialisation failed: {e} -->"))
}
