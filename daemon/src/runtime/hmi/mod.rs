//! Serving the browser HMI (issue #30, docs/hmi.md): one origin (`[hmi] listen`) answers
//! `GET /` and the HMI's static files ([`assets`]) and, on the same origin, every gRPC service
//! over grpc-web (tonic-web: `POST /cnc.v1.Machine/StreamStatus`, content type
//! `application/grpc-web+proto`) behind the same auth interceptor as the API's listeners.
//! HTTP/1.1 and HTTP/2 are both accepted (browsers speak HTTP/1.1 to a plain-text port).

pub mod assets;
pub mod fuzz;

use std::sync::Arc;

use axum::body::Body;
use http::{HeaderValue, Method, Request, Response, StatusCode, header};
use tonic::service::Routes;

pub use assets::Assets;

/// The page `/` shows when cncd was built without `hmi/dist/`.
const MISSING_PAGE: &str = "<!doctype html><meta charset=utf-8><title>cncd</title>\
<h1>The HMI assets are missing</h1>\
<p>This cncd was built without the browser HMI's files (<code>hmi/dist/</code> did not exist \
at build time). The gRPC API and grpc-web on this port work; rebuild cncd from a checkout \
that has <code>hmi/dist/</code> to get the screen (docs/hmi.md).</p>\n";

/// The HMI's routes: `routes` (every gRPC service, with its interceptor) over grpc-web, and
/// the static files for everything else. `size` is applied to the gRPC responses before their
/// translation to grpc-web (the API's message-size refusal).
pub fn app<L>(routes: Routes, size: L, assets: Arc<Assets>) -> Routes
where
    L: tower::Layer<axum::routing::Route> + Clone + Send + Sync + 'static,
    L::Service: tower::Service<axum::extract::Request, Error = std::convert::Infallible>
        + Clone
        + Send
        + Sync
        + 'static,
    <L::Service as tower::Service<axum::extract::Request>>::Response:
        axum::response::IntoResponse + 'static,
    <L::Service as tower::Service<axum::extract::Request>>::Future: Send + 'static,
{
    let router = routes
        .prepare()
        .into_axum_router()
        .route_layer(size)
        .route_layer(tonic_web::GrpcWebLayer::new())
        .fallback(move |req: axum::extract::Request| {
            let assets = assets.clone();
            async move { static_file(&assets, &req) }
        });
    Routes::from(router)
}

/// The answer to a request that is not a gRPC call of a known service.
pub fn static_file<B>(assets: &Assets, req: &Request<B>) -> Response<Body> {
    let grpc = req
        .headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|t| t.as_bytes().starts_with(b"application/grpc"));
    if grpc {
        // A gRPC call of a service this server does not have.
        return grpc_unimplemented(req.uri().path());
    }
    if req.method() != Method::GET && req.method() != Method::HEAD {
        let mut r = plain(
            StatusCode::METHOD_NOT_ALLOWED,
            "only GET and HEAD are served here\n",
        );
        r.headers_mut()
            .insert(header::ALLOW, HeaderValue::from_static("GET, HEAD"));
        return r;
    }
    let path = match req.uri().path().trim_start_matches('/') {
        "" => "index.html",
        p => p,
    };
    let Some(a) = assets.get(path) else {
        if path == "index.html" && assets.is_empty() {
            return page(StatusCode::SERVICE_UNAVAILABLE, MISSING_PAGE);
        }
        return plain(StatusCode::NOT_FOUND, "no such file in the HMI\n");
    };
    let unchanged = req
        .headers()
        .get(header::IF_NONE_MATCH)
        .is_some_and(|v| v.as_bytes() == a.etag.as_bytes());
    let (status, body) = if unchanged {
        (StatusCode::NOT_MODIFIED, Body::empty())
    } else if req.method() == Method::HEAD {
        (StatusCode::OK, Body::empty())
    } else {
        (StatusCode::OK, Body::from(a.bytes.clone()))
    };
    let mut r = Response::new(body);
    *r.status_mut() = status;
    let h = r.headers_mut();
    secure_headers(h);
    if let Ok(v) = HeaderValue::from_str(&a.content_type) {
        h.insert(header::CONTENT_TYPE, v);
    }
    h.insert(
        header::CACHE_CONTROL,
        HeaderValue::from_static(a.cache_control),
    );
    if let Ok(v) = HeaderValue::from_str(&a.etag) {
        h.insert(header::ETAG, v);
    }
    if !unchanged {
        h.insert(header::CONTENT_LENGTH, HeaderValue::from(a.bytes.len()));
    }
    r
}

/// Headers of every page: no content sniffing, no framing by other sites (the operator's
/// controls must not be clicked through an overlay), no referrer leaving the machine.
fn secure_headers(h: &mut http::HeaderMap) {
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
}

fn page(status: StatusCode, html: &'static str) -> Response<Body> {
    let mut r = Response::new(Body::from(html));
    *r.status_mut() = status;
    let h = r.headers_mut();
    secure_headers(h);
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/html; charset=utf-8"),
    );
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    r
}

fn plain(status: StatusCode, text: &'static str) -> Response<Body> {
    let mut r = Response::new(Body::from(text));
    *r.status_mut() = status;
    let h = r.headers_mut();
    secure_headers(h);
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/plain; charset=utf-8"),
    );
    r
}

fn grpc_unimplemented(path: &str) -> Response<Body> {
    let (parts, _) = tonic::Status::unimplemented(format!("no gRPC method {path}"))
        .into_http::<()>()
        .into_parts();
    Response::from_parts(parts, Body::empty())
}
