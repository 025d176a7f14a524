//! Faults injected for tests (`GLINT_FAULT`): `lost@N` or `oom@N` makes the
//! process's Nth pass submission (counted from 1) fail as
//! `VK_ERROR_DEVICE_LOST` or `VK_ERROR_OUT_OF_DEVICE_MEMORY` would, without
//! reaching the driver, so the tests can see a render or animation end
//! cleanly on a device that fails mid-way. Unset (or not of that form): no
//! fault, and nothing is counted that costs more than one atomic add.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;

use ash::vk;

/// The fault `GLINT_FAULT` asks for: the result, at which submission.
fn planned() -> Option<(vk::Result, u64)> {
    static PLAN: OnceLock<Option<(vk::Result, u64)>> = OnceLock::new();
    *PLAN.get_or_init(|| parse(&std::env::var("GLINT_FAULT").ok()?))
}

/// `lost@N` or `oom@N`, N >= 1.
fn parse(text: &str) -> Option<(vk::Result, u64)> {
    let (kind, at) = text.trim().split_once('@')?;
    let result = match kind {
        "lost" => vk::Result::ERROR_DEVICE_LOST,
        "oom" => vk::Result::ERROR_OUT_OF_DEVICE_MEMORY,
        _ => return None,
    };
    let at: u64 = at.parse().ok().filter(|&n| n >= 1)?;
    Some((result, at))
}

/// Called before each pass's `vkQueueSubmit`: the injected failure, if this
/// is the planned submission.
pub(crate) fn at_submit() -> Option<vk::Result> {
    static SUBMITS: AtomicU64 = AtomicU64::new(0);
    let (result, at) = planned()?;
    (SUBMITS.fetch_add(1, Ordering::Relaxed) + 1 == at).then_some(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_two_faults_and_nothing_else() {
        assert_eq!(parse("lost@3"), Some((vk::Result::ERROR_DEVICE_LOST, 3)));
        assert_eq!(
            parse(" oom@1\n"),
            Some((vk::Result::ERROR_OUT_OF_DEVICE_MEMORY, 1))
        );
        for bad in [
            "",
            "lost",
            "lost@0",
            "lost@-1",
            "oom@x",
            "boom@2",
            "@2",
            "lost@99999999999999999999",
        ] {
            assert_eq!(parse(bad), None, "{bad:?}");
        }
    }

    proptest::proptest! {
        /// Any text is read without a panic.
        #[test]
        fn any_text_is_read_without_a_panic(text in ".*") {
            let _ = parse(&text);
        }
    }
}
