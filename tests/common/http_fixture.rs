//! A tiny HTTP server for tests of the statistics clients (the status page and
//! `mavtables stats`) where the answer must be made to order: a failing or garbled
//! endpoint. Each request is answered by a closure given the path and the request's
//! number (from 1); the server stops when dropped.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::thread::{self, JoinHandle};
use std::time::Duration;

/// What the server does with one request.
pub enum Answer {
    /// Status code, content type, body.
    Http(u16, &'static str, Vec<u8>),
    /// These bytes exactly, then close.
    Raw(Vec<u8>),
    /// Close without a word.
    Close,
}

/// A running fixture server on 127.0.0.1.
pub struct HttpFixture {
    /// Its port.
    pub port: u16,
    /// Requests answered so far.
    pub requests: Arc<AtomicUsize>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl HttpFixture {
    /// Starts a server answering every request with `answer(path, n)`.
    pub fn start(answer: impl Fn(&str, usize) -> Answer + Send + 'static) -> HttpFixture {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind fixture");
        let port = listener.local_addr().expect("addr").port();
        let stop = Arc::new(AtomicBool::new(false));
        let requests = Arc::new(AtomicUsize::new(0));
        let (stop2, requests2) = (Arc::clone(&stop), Arc::clone(&requests));
        let thread = thread::spawn(move || {
            for conn in listener.incoming() {
                if stop2.load(Ordering::SeqCst) {
                    break;
                }
                let Ok(mut conn) = conn else { continue };
                let Some(path) = read_path(&mut conn) else {
                    continue;
                };
                let n = requests2.fetch_add(1, Ordering::SeqCst) + 1;
                let bytes = match answer(&path, n) {
                    Answer::Http(code, kind, body) => {
                        let mut head = format!(
                            "HTTP/1.1 {code} {}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\n\
                             Cache-Control: no-store\r\nConnection: close\r\n\r\n",
                            if code == 200 { "OK" } else { "Not OK" },
                            body.len()
                        )
                        .into_bytes();
                        head.extend(body);
                        head
                    }
                    Answer::Raw(bytes) => bytes,
                    Answer::Close => Vec::new(),
                };
                let _ = conn.write_all(&bytes);
            }
        });
        HttpFixture {
            port,
            requests,
            stop,
            thread: Some(thread),
        }
    }

    /// `http://127.0.0.1:PORT`
    pub fn url(&self) -> String {
        format!("http://127.0.0.1:{}", self.port)
    }
}

/// The path of the request on `conn`, once its head has arrived.
fn read_path(conn: &mut TcpStream) -> Option<String> {
    let _ = conn.set_read_timeout(Some(Duration::from_secs(5)));
    let mut head = Vec::new();
    let mut buf = [0u8; 4096];
    while !head.windows(4).any(|w| w == b"\r\n\r\n") {
        let n = conn.read(&mut buf).ok()?;
        if n == 0 || head.len() > 65536 {
            return None;
        }
        head.extend_from_slice(&buf[..n]);
    }
    let text = String::from_utf8_lossy(&head);
    text.split(' ').nth(1).map(str::to_string)
}

impl Drop for HttpFixture {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        // Wake the accept loop so it sees the flag.
        let _ = TcpStream::connect(("127.0.0.1", self.port));
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
