//! Scenes: the model (`model`), the classic format's parser (`parse`, its
//! objects in `objects`, reading in windows in `windows`, messages in
//! `diagnostic`), render settings (`settings`) and writing a scene back
//! (`write`).

mod diagnostic;
pub(crate) mod model;
pub(crate) mod number;
mod objects;
mod parse;
mod settings;
mod space;
mod windows;
mod write;

pub use diagnostic::{Diagnostic, ParseError};
pub use model::*;
pub use settings::{Effects, Settings};
pub use space::SpaceMap;
pub use windows::{parse_reader, parse_scene, read_scene};
pub use write::to_classic_text;
