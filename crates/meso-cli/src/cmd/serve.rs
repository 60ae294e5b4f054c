//! `meso serve`: the interactive NDF editor in the browser (see `docs/http-api.md`).

use anyhow::Result;

/// Serve the NDF editor: one local web page and its HTTP API.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// TCP port (0 picks a free one; the bound address is printed on stdout).
    #[arg(long, default_value_t = 7878)]
    pub port: u16,
    /// Address to bind; the default keeps the editor private to this machine.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Open the page in the default browser (xdg-open / open / start).
    #[arg(long)]
    pub open: bool,
}

/// Run the server until Ctrl-C.
pub fn run(a: Args) -> Result<()> {
    let open = a.open;
    meso_serve::run(&a.host, a.port, move |addr| {
        let url = format!("http://{addr}/");
        // The address is for whoever started the server; the server runs on without a reader.
        let _ = crate::util::print_stdout(&format!("meso serve: listening on {url}\n"));
        if open {
            let opener = if cfg!(target_os = "macos") {
                "open"
            } else if cfg!(windows) {
                "explorer"
            } else {
                "xdg-open"
            };
            if let Err(e) = std::process::Command::new(opener).arg(&url).spawn() {
                note!("meso serve: cannot open a browser ({opener}: {e}); open {url}");
            }
        }
    })?;
    Ok(())
}
