//! A small WebDriver client (the W3C protocol, JSON over HTTP/1.1 on loopback) that drives
//! Debian's chromedriver and headless Chromium, for tests that click through a page as a
//! user would: open it, find elements by CSS selector, click them, read text and
//! attributes. chromedriver and the browser end with the [`Browser`].

use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};

/// A headless Chromium driven through chromedriver.
pub struct Browser {
    driver: Child,
    port: u16,
    session: String,
}

/// An element of the page (its WebDriver reference).
#[derive(Clone, Debug)]
pub struct Element(String);

/// The key W3C WebDriver names element references by.
const ELEMENT: &str = "element-6066-11e4-a52e-4f735466cecf";

impl Browser {
    /// Starts chromedriver on a free loopback port and a headless `chromium` with a fresh
    /// profile in `profile`; None when chromedriver is not installed.
    pub fn start(chromium: &str, profile: &Path) -> Option<Browser> {
        if !crate::installed("chromedriver") {
            return None;
        }
        let mut driver = Command::new("chromedriver")
            .args(["--port=0", "--allowed-ips=127.0.0.1"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver starts");
        // It says which port it took once it listens.
        let mut lines = BufReader::new(driver.stdout.take().expect("piped"));
        let mut port = None;
        let mut line = String::new();
        while port.is_none() {
            line.clear();
            if lines.read_line(&mut line).expect("chromedriver's output") == 0 {
                let _ = driver.kill();
                panic!("chromedriver ended before it listened");
            }
            port = line
                .split("started successfully on port ")
                .nth(1)
                .and_then(|rest| rest.trim().trim_end_matches('.').parse::<u16>().ok());
        }
        // Keep reading its output so it never blocks on a full pipe.
        std::thread::spawn(move || {
            let mut sink = Vec::new();
            let _ = lines.read_to_end(&mut sink);
        });
        let mut b = Browser {
            driver,
            port: port.expect("a port"),
            session: String::new(),
        };
        // The flags a closed machine needs: no network chatter, no first-run work.
        let args = [
            "--headless".to_string(),
            "--no-sandbox".into(),
            "--disable-gpu".into(),
            "--disable-quic".into(),
            "--no-first-run".into(),
            "--disable-background-networking".into(),
            "--disable-component-update".into(),
            "--disable-sync".into(),
            "--window-size=1400,1000".into(),
            format!("--user-data-dir={}", profile.display()),
        ];
        let chromium_path = crate::which(chromium).unwrap_or_else(|| chromium.into());
        let created = b.call(
            "POST",
            "/session",
            Some(json!({"capabilities": {"alwaysMatch": {
                "browserName": "chrome",
                "goog:loggingPrefs": {"browser": "ALL"},
                "goog:chromeOptions": {"binary": chromium_path, "args": args},
            }}})),
        );
        b.session = created["value"]["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no session: {created}"))
            .to_string();
        Some(b)
    }

    /// Opens `url` and waits for the page to load (WebDriver's navigate returns then).
    pub fn goto(&self, url: &str) {
        self.session_call("POST", "/url", Some(json!({ "url": url })));
    }

    /// The first element matching the CSS `selector`.
    pub fn find(&self, selector: &str) -> Element {
        let v = self.session_call(
            "POST",
            "/element",
            Some(json!({"using": "css selector", "value": selector})),
        );
        element(&v).unwrap_or_else(|| panic!("no element {selector}: {v}"))
    }

    /// Every element matching `selector`, in document order.
    pub fn find_all(&self, selector: &str) -> Vec<Element> {
        let v = self.session_call(
            "POST",
            "/elements",
            Some(json!({"using": "css selector", "value": selector})),
        );
        v.as_array()
            .unwrap_or_else(|| panic!("elements {selector}: {v}"))
            .iter()
            .map(|e| element(e).expect("an element reference"))
            .collect()
    }

    /// Clicks `e` as a user would: scrolled into view, at its centre, by a real pointer
    /// event (refused if another element covers it).
    pub fn click(&self, e: &Element) {
        self.session_call("POST", &format!("/element/{}/click", e.0), Some(json!({})));
    }

    /// The text `e` shows.
    pub fn text(&self, e: &Element) -> String {
        let v = self.session_call("GET", &format!("/element/{}/text", e.0), None);
        v.as_str().unwrap_or_default().to_string()
    }

    /// Attribute `name` of `e`, if it has one.
    pub fn attribute(&self, e: &Element, name: &str) -> Option<String> {
        let v = self.session_call("GET", &format!("/element/{}/attribute/{name}", e.0), None);
        v.as_str().map(String::from)
    }

    /// Whether `e` is displayed.
    pub fn displayed(&self, e: &Element) -> bool {
        let v = self.session_call("GET", &format!("/element/{}/displayed", e.0), None);
        v.as_bool().unwrap_or(false)
    }

    /// Runs `script` in the page (its `return` value comes back).
    pub fn script(&self, script: &str) -> Value {
        self.session_call(
            "POST",
            "/execute/sync",
            Some(json!({"script": script, "args": []})),
        )
    }

    /// The page's console errors since the last call (uncaught exceptions, failed loads).
    pub fn console_errors(&self) -> Vec<String> {
        let v = self.session_call("POST", "/se/log", Some(json!({"type": "browser"})));
        v.as_array()
            .into_iter()
            .flatten()
            .filter(|e| e["level"] == "SEVERE")
            .map(|e| e["message"].as_str().unwrap_or_default().to_string())
            .collect()
    }

    fn session_call(&self, method: &str, path: &str, body: Option<Value>) -> Value {
        let path = format!("/session/{}{path}", self.session);
        self.call(method, &path, body)["value"].clone()
    }

    /// One request; panics with the driver's message on an error status.
    fn call(&self, method: &str, path: &str, body: Option<Value>) -> Value {
        let body = body.map(|b| b.to_string()).unwrap_or_default();
        let mut s = TcpStream::connect(("127.0.0.1", self.port)).expect("chromedriver listens");
        // A driver that never answers fails the test instead of hanging it.
        s.set_read_timeout(Some(std::time::Duration::from_secs(300)))
            .expect("a read timeout");
        write!(
            s,
            "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
            self.port,
            body.len()
        )
        .expect("request sent");
        // Read the head, then exactly the body it announces: the driver may keep the
        // connection open whatever the request asked.
        let mut r = BufReader::new(s);
        let mut head = String::new();
        loop {
            let mut line = String::new();
            if r.read_line(&mut line).expect("response read") == 0 || line == "\r\n" {
                break;
            }
            head.push_str(&line);
        }
        let header = |name: &str| {
            head.lines().find_map(|l| {
                let (k, v) = l.split_once(':')?;
                k.trim()
                    .eq_ignore_ascii_case(name)
                    .then(|| v.trim().to_string())
            })
        };
        let text = if let Some(n) = header("content-length") {
            let mut body = vec![0; n.parse().expect("a length")];
            r.read_exact(&mut body).expect("response body");
            String::from_utf8_lossy(&body).into_owned()
        } else if header("transfer-encoding").is_some_and(|v| v.eq_ignore_ascii_case("chunked")) {
            unchunk(&mut r)
        } else {
            let mut body = String::new();
            r.read_to_string(&mut body).expect("response body");
            body
        };
        let v: Value = serde_json::from_str(&text)
            .unwrap_or_else(|e| panic!("{method} {path}: {e}: {head}\n{text}"));
        let status = head.split(' ').nth(1).unwrap_or("0");
        assert!(
            status.starts_with('2'),
            "{method} {path} -> {status}: {}",
            v["value"]
        );
        v
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        if !self.session.is_empty() {
            // Ends the browser; chromedriver then ends below.
            let path = format!("/session/{}", self.session);
            let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                self.call("DELETE", &path, None)
            }));
        }
        let _ = self.driver.kill();
        let _ = self.driver.wait();
    }
}

fn element(v: &Value) -> Option<Element> {
    v.get(ELEMENT)
        .and_then(Value::as_str)
        .map(|s| Element(s.to_string()))
}

/// The body of a chunked HTTP response.
fn unchunk(r: &mut impl BufRead) -> String {
    let mut out = Vec::new();
    loop {
        let mut size = String::new();
        r.read_line(&mut size).expect("chunk size");
        let n = usize::from_str_radix(size.trim(), 16).expect("a chunk size");
        let mut chunk = vec![0; n + 2];
        r.read_exact(&mut chunk).expect("a chunk");
        if n == 0 {
            break;
        }
        out.extend_from_slice(&chunk[..n]);
    }
    String::from_utf8_lossy(&out).into_owned()
}
