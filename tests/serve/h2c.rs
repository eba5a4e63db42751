//! HTTP/2 without TLS (h2c, prior knowledge) on the same port as HTTP/1.1: a client that
//! multiplexes gets the same bytes.

use super::{Server, root};
use bytes::Bytes;
use http_body_util::{BodyExt, Empty};
use hyper_util::client::legacy::Client;
use hyper_util::rt::TokioExecutor;
use std::time::Duration;

#[test]
fn an_h2c_client_gets_ranges_over_one_connection() {
    let server = Server::start_in(&super::root(), &["--quiet"]);
    let disk = std::fs::read(root().join("city.strata/octree.bin")).expect("read");
    let url = format!("http://{}/city.strata/octree.bin", server.addr);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    let client: Client<_, Empty<Bytes>> = Client::builder(TokioExecutor::new())
        .http2_only(true)
        .build_http();
    let ranges: Vec<(usize, usize)> = (0..32)
        .map(|i| {
            let start = (i * 7919 * 131) % (disk.len() - 70_000);
            (start, start + 1 + (i * 2111) % 65_536)
        })
        .collect();
    let answers = runtime.block_on(async {
        let fetches = ranges.iter().map(|&(a, b)| {
            let req = hyper::Request::get(&url)
                .header("Range", format!("bytes={a}-{}", b - 1))
                .body(Empty::new())
                .expect("request");
            let client = client.clone();
            async move {
                let resp = client.request(req).await.expect("an h2c answer");
                let (parts, body) = resp.into_parts();
                let bytes = body.collect().await.expect("body").to_bytes();
                (parts.status, parts.version, bytes)
            }
        });
        let all = futures_join(fetches.collect());
        tokio::time::timeout(Duration::from_secs(20), all)
            .await
            .expect("h2c answers within 20 s")
    });
    for ((status, version, bytes), (a, b)) in answers.into_iter().zip(ranges) {
        assert_eq!(status, 206);
        assert_eq!(version, hyper::Version::HTTP_2);
        assert_eq!(bytes[..], disk[a..b], "bytes {a}..{b} differ over h2c");
    }
}

/// Runs `futures` concurrently (on one connection, as h2 streams) and returns their outputs in
/// order.
async fn futures_join<F: std::future::Future + Send + 'static>(futures: Vec<F>) -> Vec<F::Output>
where
    F::Output: Send + 'static,
{
    let handles: Vec<_> = futures.into_iter().map(tokio::spawn).collect();
    let mut out = Vec::with_capacity(handles.len());
    for h in handles {
        out.push(h.await.expect("task"));
    }
    out
}
