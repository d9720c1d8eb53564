//! The web page's files, built into the binary (no build step: plain HTML, CSS and
//! JavaScript in `crates/kerf/assets/`).

use axum::http::header;
use axum::response::{IntoResponse, Response};

/// `index.html`.
pub const HTML: &str = include_str!("../../assets/index.html");
/// `app.js`.
pub const SCRIPT: &str = include_str!("../../assets/app.js");
/// `style.css`.
pub const STYLE: &str = include_str!("../../assets/style.css");

fn file(content_type: &'static str, body: &'static str) -> Response {
    ([(header::CONTENT_TYPE, content_type)], body).into_response()
}

/// The page.
pub fn html() -> Response {
    file("text/html; charset=utf-8", HTML)
}

/// Its script.
pub fn script() -> Response {
    file("text/javascript; charset=utf-8", SCRIPT)
}

/// Its style sheet.
pub fn style() -> Response {
    file("text/css; charset=utf-8", STYLE)
}
