//! `vademecum serve --agones` against a fake Agones SDK sidecar (the sidecar's gRPC contract,
//! `proto/agones/`, served here): Ready once serving, health pings, the Counter "sessions" at
//! the sessions held (capacity --max-sessions), Allocated while it holds any, Ready again when
//! the last closes, Shutdown once drained; and a clear refusal when no sidecar answers.

use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tonic::{Request, Response, Status, Streaming};
use vademecum_client::{Client, SceneSpec};
use vademecum_proto::agones::{beta, sdk};

use crate::util;

/// What the fake sidecar was told.
#[derive(Debug, Default)]
struct Told {
    /// State changes in order ("Ready", "Allocate", "Shutdown").
    states: Vec<&'static str>,
    /// The sessions Counter: (count, capacity).
    counter: (i64, i64),
    health_pings: u64,
}

#[derive(Clone, Default)]
struct Sidecar(Arc<Mutex<Told>>);

impl Sidecar {
    fn told(&self) -> std::sync::MutexGuard<'_, Told> {
        self.0.lock().unwrap()
    }

    fn state(&self, s: &'static str) -> Result<Response<sdk::Empty>, Status> {
        self.told().states.push(s);
        Ok(Response::new(sdk::Empty {}))
    }

    /// Waits (at most 20 s) until `what` holds of what the sidecar was told.
    fn wait_for(&self, why: &str, what: impl Fn(&Told) -> bool) {
        let until = Instant::now() + Duration::from_secs(20);
        while !what(&self.told()) {
            assert!(Instant::now() < until, "{why}: the sidecar was told {:?}", self.told());
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

#[tonic::async_trait]
impl sdk::sdk_server::Sdk for Sidecar {
    async fn ready(&self, _: Request<sdk::Empty>) -> Result<Response<sdk::Empty>, Status> {
        self.state("Ready")
    }
    async fn allocate(&self, _: Request<sdk::Empty>) -> Result<Response<sdk::Empty>, Status> {
        self.state("Allocate")
    }
    async fn shutdown(&self, _: Request<sdk::Empty>) -> Result<Response<sdk::Empty>, Status> {
        self.state("Shutdown")
    }
    async fn health(&self, req: Request<Streaming<sdk::Empty>>) -> Result<Response<sdk::Empty>, Status> {
        let mut pings = req.into_inner();
        while let Ok(Some(_)) = pings.message().await {
            self.told().health_pings += 1;
        }
        Ok(Response::new(sdk::Empty {}))
    }
    async fn get_game_server(&self, _: Request<sdk::Empty>) -> Result<Response<sdk::GameServer>, Status> {
        Ok(Response::new(sdk::GameServer::default()))
    }
    type WatchGameServerStream = tokio_stream::Empty<Result<sdk::GameServer, Status>>;
    async fn watch_game_server(&self, _: Request<sdk::Empty>) -> Result<Response<Self::WatchGameServerStream>, Status> {
        Err(Status::unimplemented("not called by the server"))
    }
    async fn set_label(&self, _: Request<sdk::KeyValue>) -> Result<Response<sdk::Empty>, Status> {
        Err(Status::unimplemented("not called by the server"))
    }
    async fn set_annotation(&self, _: Request<sdk::KeyValue>) -> Result<Response<sdk::Empty>, Status> {
        Err(Status::unimplemented("not called by the server"))
    }
    async fn reserve(&self, _: Request<sdk::Duration>) -> Result<Response<sdk::Empty>, Status> {
        Err(Status::unimplemented("not called by the server"))
    }
}

#[tonic::async_trait]
impl beta::sdk_server::Sdk for Sidecar {
    async fn get_counter(&self, req: Request<beta::GetCounterRequest>) -> Result<Response<beta::Counter>, Status> {
        let (count, capacity) = self.told().counter;
        Ok(Response::new(beta::Counter {
            name: req.into_inner().name,
            count,
            capacity,
        }))
    }
    async fn update_counter(&self, req: Request<beta::UpdateCounterRequest>) -> Result<Response<beta::Counter>, Status> {
        let u = req
            .into_inner()
            .counter_update_request
            .ok_or_else(|| Status::invalid_argument("no update"))?;
        if u.name != "sessions" {
            return Err(Status::not_found(format!("no counter {}", u.name)));
        }
        let mut t = self.told();
        if let Some(c) = u.capacity {
            t.counter.1 = c;
        }
        if let Some(c) = u.count {
            if c > t.counter.1 {
                return Err(Status::out_of_range("count above capacity"));
            }
            t.counter.0 = c;
        }
        t.counter.0 += u.count_diff;
        Ok(Response::new(beta::Counter {
            name: u.name,
            count: t.counter.0,
            capacity: t.counter.1,
        }))
    }
}

#[test]
fn an_agones_game_server_is_ready_counts_its_sessions_is_allocated_while_it_holds_any_and_shuts_down_drained() {
    let rt = util::runtime();
    let sidecar = Sidecar::default();
    let listener = rt.block_on(tokio::net::TcpListener::bind("127.0.0.1:0")).unwrap();
    let port = listener.local_addr().unwrap().port();
    rt.spawn(
        tonic::transport::Server::builder()
            .add_service(sdk::sdk_server::SdkServer::new(sidecar.clone()))
            .add_service(beta::sdk_server::SdkServer::new(sidecar.clone()))
            .serve_with_incoming(tokio_stream::wrappers::TcpListenerStream::new(listener)),
    );
    let server = util::Server::start(
        &["--agones", "--max-sessions", "3"],
        &[("AGONES_SDK_GRPC_PORT", &port.to_string()), ("VADEMECUM_TOKENS", "t")],
    );
    sidecar.wait_for("Ready once serving, with the Counter's capacity", |t| {
        t.states == ["Ready"] && t.counter == (0, 3)
    });
    sidecar.wait_for("health pings", |t| t.health_pings >= 1);

    rt.block_on(async {
        let client = Client::connect_with_token(server.url.clone(), Some("t")).await.unwrap();
        let scene = || SceneSpec::Builtin("organ".into());
        let one = client.create_session(scene(), "organ", "one").await.unwrap();
        sidecar.wait_for("Allocated with its first session", |t| {
            t.states == ["Ready", "Allocate"] && t.counter.0 == 1
        });
        let two = client.create_session(scene(), "organ", "two").await.unwrap();
        sidecar.wait_for("counted, not allocated twice", |t| t.counter.0 == 2);
        one.close().await.unwrap();
        two.close().await.unwrap();
        sidecar.wait_for("back to the pool when the last closes", |t| {
            t.states == ["Ready", "Allocate", "Ready"] && t.counter.0 == 0
        });

        // draining with a session running: stays allocated; shut down once it closes
        let three = client.create_session(scene(), "organ", "three").await.unwrap();
        sidecar.wait_for("allocated again", |t| t.states.len() == 4 && t.counter.0 == 1);
        let drain = std::process::Command::new(util::vademecum_bin())
            .args(["drain", "--addr", &server.url, "--wait", "0", "--token", "t"])
            .output()
            .unwrap();
        assert_eq!(drain.status.code(), Some(1), "{}", String::from_utf8_lossy(&drain.stdout));
        tokio::time::sleep(Duration::from_millis(300)).await;
        assert!(!sidecar.told().states.contains(&"Shutdown"), "{:?}", sidecar.told());
        three.close().await.unwrap();
        sidecar.wait_for("Shutdown once drained", |t| {
            t.states == ["Ready", "Allocate", "Ready", "Allocate", "Shutdown"] && t.counter.0 == 0
        });
    });
    let pings = sidecar.told().health_pings;
    assert!(pings >= 1, "{pings}");
}

/// A sidecar port that is not a port number is refused at once, with the variable named.
#[test]
fn serve_with_agones_refuses_a_sidecar_port_that_is_not_a_port() {
    let o = Command::new(util::vademecum_bin())
        .args(["serve", "--listen", "127.0.0.1:0", "--no-auth", "--agones"])
        .env("AGONES_SDK_GRPC_PORT", "ninety")
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("AGONES_SDK_GRPC_PORT=\"ninety\" is not a port number"), "{err}");
}
