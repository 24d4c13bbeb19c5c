//! The viewer's panels, one file each, every one a `show` function that draws its widgets into
//! the `egui::Ui` it is given and changes the [`super::controller::Controller`] through them.
//! [`super::app::ViewerApp`] lays them out: left [`compare`] then [`numbers`]; right [`scene`],
//! [`inspector`] then [`probe`]; the [`time_bar`] at the bottom; [`help`] as a window. A new
//! panel is a new file here and one call in that layout.

pub mod compare;
pub mod help;
pub mod inspector;
pub mod numbers;
pub mod probe;
pub mod scene;
pub mod time_bar;
