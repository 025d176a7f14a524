//! Scenes: the model (`model`), the classic format's parser (`parse`, its
//! objects in `objects`, reading in windows in `windows`, messages in
//! `diagnostic`), render settings (`settings`), a model file's mesh as
//! triangles (`mesh`), a model file alone framed as a scene (`framed`) and writing a scene back (`write`, and as OBJ in `obj`).

mod diagnostic;
mod framed;
pub mod mesh;
pub(crate) mod model;
mod obj;
mod objects;
mod parse;
mod settings;
mod space;
mod windows;
mod write;

pub use diagnostic::{Diagnostic, ParseError};
pub use framed::{model_scene, MODEL_MATERIAL};
pub use model::*;
pub use obj::{write_obj, ObjWritten};
pub use settings::{Effects, Sampler, Settings};
pub use space::SpaceMap;
pub use windows::{parse_reader, parse_scene, read_scene};
pub use write::to_classic_text;
