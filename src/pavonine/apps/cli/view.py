"""``pavonine view ASSET|STAGE``: look development in the browser, live iridescence."""

from __future__ import annotations

import errno
from pathlib import Path

import click

from pavonine.apps.cli.options import say
from pavonine.base.errors import InputError, one_line_errors


@click.command("view")
@click.argument("stage", type=click.Path(path_type=Path))
@click.option(
    "--port",
    type=click.IntRange(min=0, max=65535),
    default=0,
    show_default=True,
    help="Port on 127.0.0.1 (0: a free one).",
)
@click.option("--open", "open_browser", is_flag=True, help="Open the page in the default browser.")
@click.option(
    "--render-spp",
    type=click.IntRange(min=1, max=256),
    default=16,
    show_default=True,
    help="Samples per pixel of 'Render this view'.",
)
@one_line_errors
def view(stage: Path, port: int, open_browser: bool, render_spp: int) -> None:
    """Serve a page on 127.0.0.1 that draws STAGE (an asset, its folder, or a scene) in real time.

    three.js (bundled, nothing fetched) with the feather BRDF tabulated per ocellar class and
    gradation: orbit the camera, turn the sun, set the sky, switch the lod variant, read the
    class and gradation under the cursor; "Render this view" runs pavonine render on the page's
    camera and sun and shows it beside the live view. Prints the URL; Ctrl-C stops it.
    Reference: docs/view.md.
    """
    from pavonine.apps.view.scene import stage_path
    from pavonine.apps.view.server import ViewServer, ViewState

    state = ViewState(stage_path(stage), render_spp=render_spp)
    try:
        server = ViewServer(state, port)
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise InputError("--port", f"{port} is in use on 127.0.0.1") from None
        raise InputError("--port", f"cannot listen on 127.0.0.1:{port}: {exc.strerror}") from None
    try:
        state.scene({})  # read the stage (and build its BRDF tables) before printing the URL
    except BaseException:
        server.server_close()
        raise
    say(f"serving {state.path} at {server.url}  (Ctrl-C stops)")
    if open_browser:
        import webbrowser

        webbrowser.open(server.url)
    try:
        server.serve_forever(poll_interval=0.2)
    except KeyboardInterrupt:
        say("stopped")
    finally:
        server.server_close()
