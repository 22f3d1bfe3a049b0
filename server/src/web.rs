//! The browser viewer (`vademecum serve --web ADDR`): a single page compiled into the binary
//! (`server/web/`: no library, nothing fetched at run time) and gRPC-web (tonic-web, HTTP/1.1)
//! on the same `Sessions`, `Viewing` and `Info` services as the gRPC port — the same
//! contracts, the same bearer tokens (the page asks for one when the server has them), the
//! same limits. CORS lets pages served elsewhere call them too when the server has tokens: a
//! bearer token is a header, not an ambient cookie, so another origin gains nothing it was not
//! given. Without tokens (`--no-auth`) only the origins named by `--web-origin` may (none by
//! default: the viewer's own page needs no CORS), so that a page on any site cannot drive a
//! lab's open server from a browser on its network.

use axum::http::{HeaderMap, HeaderName, Method, StatusCode, header};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use tonic::service::Routes;
use tonic::service::interceptor::InterceptedService;
use tonic_web::GrpcWebLayer;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_layer::Layer;
use vademecum_proto::v1 as pb;

use crate::auth::Auth;
use crate::service::{info::InfoService, sessions::SessionsService, viewing::ViewingService};

/// The page.
pub const INDEX_HTML: &str = include_str!("../web/index.html");
/// Its script.
pub const VIEWER_JS: &str = include_str!("../web/viewer.js");

/// The services a browser calls, as gRPC-web.
pub struct WebServices {
    /// `vademecum.v1.Sessions`.
    pub sessions: pb::sessions_server::SessionsServer<SessionsService>,
    /// `vademecum.v1.Viewing`.
    pub viewing: pb::viewing_server::ViewingServer<ViewingService>,
    /// `vademecum.v1.Info`.
    pub info: pb::info_server::InfoServer<InfoService>,
}

/// Which origins' pages may call the services (see the [module docs](self)).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origins {
    /// Any origin (a server with tokens, no `--web-origin`).
    Any,
    /// These origins only (`--web-origin`; empty: none but the viewer's own).
    Only(Vec<String>),
}

impl Origins {
    /// The origins of a server with `tokens` (or none) and the `named` origins.
    pub fn of(tokens: bool, named: &[String]) -> Self {
        match (tokens, named.is_empty()) {
            (true, true) => Origins::Any,
            _ => Origins::Only(named.to_vec()),
        }
    }
}

/// CORS for gRPC-web calls from `origins`: the headers gRPC-web sends and reads.
fn cors(origins: &Origins) -> CorsLayer {
    let h = |s: &'static str| HeaderName::from_static(s);
    let allow = match origins {
        Origins::Any => AllowOrigin::any(),
        Origins::Only(list) => AllowOrigin::list(list.iter().filter_map(|o| o.parse().ok())),
    };
    CorsLayer::new()
        .allow_origin(allow)
        .allow_methods([Method::POST, Method::GET, Method::OPTIONS])
        .allow_headers([
            header::CONTENT_TYPE,
            header::AUTHORIZATION,
            h("x-grpc-web"),
            h("x-user-agent"),
            h("grpc-timeout"),
        ])
        .expose_headers([h("grpc-status"), h("grpc-message"), h("grpc-status-details-bin")])
}

/// What answers a path that is neither the page nor a service's method: a gRPC (or gRPC-web)
/// call gets `UNIMPLEMENTED`, as from the gRPC port; anything else — a mistyped address in a
/// browser — a plain 404 that says where the viewer is.
async fn not_found(headers: HeaderMap) -> Response {
    let grpc = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/grpc"));
    if grpc {
        tonic::Status::unimplemented("no such service or method").into_http()
    } else {
        (StatusCode::NOT_FOUND, "not found: the viewer is at /\n").into_response()
    }
}

/// Serves the page and gRPC-web on `listener` (with TLS when `tls` gives a certificate chain
/// and key, as the gRPC port) until `shutdown` resolves.
pub async fn serve(
    listener: tokio::net::TcpListener,
    services: WebServices,
    auth: Auth,
    origins: Origins,
    tls: Option<(Vec<u8>, Vec<u8>)>,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> anyhow::Result<()> {
    // gRPC-web per service: the page's own routes are plain HTTP/1.1, which a server-wide
    // gRPC-web layer would refuse
    let web = GrpcWebLayer::new();
    let routes = Routes::new(web.layer(InterceptedService::new(services.sessions, auth.clone())))
        .add_service(web.layer(InterceptedService::new(services.viewing, auth.clone())))
        .add_service(web.layer(InterceptedService::new(services.info, auth)))
        .into_axum_router()
        .route("/", get(|| async { Html(INDEX_HTML) }))
        .route(
            "/viewer.js",
            get(|| async { ([(header::CONTENT_TYPE, "text/javascript; charset=utf-8")], VIEWER_JS).into_response() }),
        )
        .fallback(not_found);
    let mut builder = tonic::transport::Server::builder();
    if let Some((cert, key)) = &tls {
        builder = builder.tls_config(tonic::transport::ServerTlsConfig::new().identity(tonic::transport::Identity::from_pem(cert, key)))?;
    }
    builder
        .accept_http1(true)
        .layer(cors(&origins))
        .add_routes(Routes::from(routes))
        .serve_with_incoming_shutdown(crate::incoming(listener), shutdown)
        .await?;
    Ok(())
}
