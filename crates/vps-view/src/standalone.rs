//! The viewer's page as one self-contained HTML document with its data inlined: no server, no
//! request, nothing fetched. A study's `report.html` embeds it (in an `<iframe srcdoc>`) as its
//! turnable 3D view; it can also be saved and opened on its own.
//!
//! The page and its script are the live viewer's own (`assets/index.html`, `assets/app.js`): the
//! script reads `window.VPS_EMBEDDED` when it is set, instead of fetching `/state`, `/scene` and
//! the `/scene/*` buffers, and never opens the WebSocket. The buffers are inlined as base64 of the
//! same little-endian f32 bytes the routes serve.

use crate::content::encode_points;
use crate::mesh::encode_triangles;
use crate::server::{APP_JS, INDEX_HTML};
use crate::state::{ViewState, ViewStatus};
use crate::ViewerContent;
use serde_json::{json, Value};

/// The script tag of `assets/index.html` that the standalone page replaces with inline scripts.
const SCRIPT_TAG: &str = "<script src=\"/app.js\"></script>";

/// The page for `content` as one HTML document (UTF-8) with every route's data inlined; the
/// status is "offline" (no loop). Allocates about 1.4 × the drawn buffers' bytes (base64).
pub fn standalone_page(content: &ViewerContent) -> String {
    let files = json!({
        "/scene/boxes": base64(&encode_points(&content.boxes)),
        "/scene/shell": base64(&encode_points(&content.shell)),
        "/scene/mesh": base64(&encode_triangles(&content.mesh)),
        "/scene/part_mesh": base64(&encode_triangles(&content.part_mesh)),
        "/scene/swept_mesh": base64(&encode_triangles(&content.swept_mesh)),
        "/scene/other_part_meshes": base64(&encode_triangles(&content.other_part_meshes)),
    });
    let state = ViewState {
        status: ViewStatus::Offline,
        frame: None,
    };
    let data = json!({
        "state": serde_json::to_value(&state).unwrap_or(Value::Null),
        "scene": serde_json::to_value(&content.meta).unwrap_or(Value::Null),
        "files": files,
    });
    let scripts = format!(
        "<script>window.VPS_EMBEDDED = {};</script>\n<script>\n{}</script>",
        script_safe(&data.to_string()),
        APP_JS
    );
    INDEX_HTML.replacen(SCRIPT_TAG, &scripts, 1)
}

/// JSON text made safe inside a `<script>` element: no `</script>` or `<!--` can appear (`<` is
/// written `\u003c`, which JSON and JavaScript both read as `<`).
fn script_safe(json: &str) -> String {
    json.replace('<', "\\u003c")
}

/// Standard base64 (RFC 4648, with padding).
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::content::tests::slab;
    use crate::SceneLimits;

    #[test]
    fn base64_matches_rfc_4648_test_vectors() {
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(plain.as_bytes()), coded);
        }
    }

    #[test]
    fn the_page_inlines_its_script_and_data_and_refers_to_nothing_outside() {
        let content = ViewerContent::new(
            "a </script> <!-- label",
            slab(),
            None,
            SceneLimits::default(),
        );
        let page = standalone_page(&content);
        assert!(!page.contains(SCRIPT_TAG));
        assert!(page.contains("window.VPS_EMBEDDED = "));
        // The label's markup is inert: only the page's own two script elements close.
        assert_eq!(page.matches("</script>").count(), 2);
        assert!(!page.contains("<!--"));
        for outside in ["src=", "http:", "https:", "@import", "url("] {
            assert!(!page.contains(outside), "{outside}");
        }
        // The script's own text never closes its element early.
        assert!(!APP_JS.contains("</script"));
        assert!(!APP_JS.contains("<!--"));
    }
}
