//! Images and their files: the float framebuffer and the 8-bit image a
//! render hands back (`framebuffer`), their encoders (`encode`), comparing
//! two of them (`compare`), and the workers that write an animation's
//! frames while the next renders (`write_queue`).

pub mod compare;
pub mod encode;
pub mod framebuffer;
pub mod write_queue;
