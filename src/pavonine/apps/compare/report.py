"""Static HTML report of render comparisons: per scene, render, baseline, heat-maps and numbers.

The page is self-contained (relative image paths, no network) so CI can publish the folder as an
artefact. A small inline script records, for every ``<img>``, whether it decoded (``naturalWidth``)
into ``#image-status``; headless browsers and people alike can read it.
"""

from __future__ import annotations

import datetime as _dt
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pavonine.apps.compare.methods import ComparisonResult
from pavonine.base.commit import atomic_path
from pavonine.render.imageio import write_display_png, write_png

_TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{{ title }}</title>
<style>
 body { font: 14px/1.4 system-ui, sans-serif; margin: 1.5em; background: #fafafa; color: #222; }
 h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 2em; }
 .pass { color: #176b2c; } .fail { color: #b3261e; }
 .badge { font-weight: 600; padding: 0.1em 0.5em; border-radius: 0.3em; background: #eee; }
 .row { display: flex; flex-wrap: wrap; gap: 1em; align-items: flex-start; }
 .tables { margin-top: 1em; }
 figure { margin: 0; } figcaption { font-size: 0.85em; color: #555; text-align: center; }
 img { width: {{ display_width }}px; image-rendering: pixelated; border: 1px solid #ccc;
       background: #000; display: block; }
 table { border-collapse: collapse; font-size: 0.9em; }
 td, th { border: 1px solid #ddd; padding: 0.2em 0.6em; text-align: left; }
 th { background: #f0f0f0; } .meta { color: #666; font-size: 0.85em; }
 #image-status { display: none; }
</style>
</head>
<body>
<h1>{{ title }}</h1>
<p class="meta">{{ created }} · {{ scenes|length }} scene(s) ·
 <span class="{{ 'pass' if all_passed else 'fail' }} badge">{{ 'all passed' if all_passed else 'differences found' }}</span></p>
<p class="meta">Heat-maps: <b>stat</b> shows |z| / z<sub>critical</sub> per block at the finest block size
that failed (per pixel when none failed; black 0, red 1 = failing edge, pale yellow ≥ 2);
<b>flip</b> shows the per-pixel FLIP error (0–1, magma).</p>
<table>
<tr><th>scene</th><th>result</th>{% for m in methods %}<th>{{ m }}</th>{% endfor %}</tr>
{% for s in scenes %}<tr><td><a href="#{{ s.anchor }}">{{ s.name }}</a></td>
<td class="{{ 'pass' if s.passed else 'fail' }}">{{ 'pass' if s.passed else 'FAIL' }}</td>
{% for m in methods %}{% set r = s.result(m) %}<td class="{{ 'pass' if r and r.passed else 'fail' }}">{{ ('pass' if r.passed else 'FAIL') if r else '—' }}</td>{% endfor %}</tr>
{% endfor %}</table>
{% for s in scenes %}
<h2 id="{{ s.anchor }}">{{ s.name }} <span class="{{ 'pass' if s.passed else 'fail' }} badge">{{ 'pass' if s.passed else 'FAIL' }}</span></h2>
{% if s.notes %}<ul>{% for n in s.notes %}<li>{{ n }}</li>{% endfor %}</ul>{% endif %}
<div class="row">
 <figure><img src="{{ s.images.render }}" alt="{{ s.name }} render"><figcaption>render</figcaption></figure>
 <figure><img src="{{ s.images.baseline }}" alt="{{ s.name }} baseline"><figcaption>baseline</figcaption></figure>
 {% for r in s.results %}<figure><img src="{{ s.images[r.method] }}" alt="{{ s.name }} {{ r.method }} heat-map">
 <figcaption>{{ r.method }} heat-map</figcaption></figure>{% endfor %}
</div>
<div class="row tables">
 {% for r in s.results %}<table><tr><th colspan="2">{{ r.method }}:
 <span class="{{ 'pass' if r.passed else 'fail' }}">{{ 'pass' if r.passed else 'FAIL' }}</span></th></tr>
 {% for k, v in r.numbers.items() %}<tr><td>{{ k }}</td><td>{{ v }}</td></tr>{% endfor %}</table>{% endfor %}
 {% if s.metadata %}<table><tr><th colspan="2">how made</th></tr>
 {% for k, v in s.metadata.items() %}<tr><td>{{ k }}</td><td>{{ v }}</td></tr>{% endfor %}</table>{% endif %}
</div>
{% endfor %}
<pre id="image-status"></pre>
<script>
window.addEventListener("load", function () {
  var lines = [];
  document.querySelectorAll("img").forEach(function (img) {
    lines.push((img.complete && img.naturalWidth > 0 ? "loaded " : "broken ") +
               img.naturalWidth + "x" + img.naturalHeight + " " + img.getAttribute("src"));
  });
  document.getElementById("image-status").textContent = lines.join("\\n");
  document.body.setAttribute("data-images-checked", String(lines.length));
});
</script>
</body>
</html>
"""


@dataclass
class SceneEntry:
    """One scene's row of the report: linear images, comparison results and how it was made."""

    name: str
    render: np.ndarray
    baseline: np.ndarray
    results: list[ComparisonResult]
    metadata: dict[str, object] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    images: dict[str, str] = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        return all(r.passed for r in self.results)

    @property
    def anchor(self) -> str:
        return re.sub(r"[^A-Za-z0-9_-]", "-", self.name)

    def result(self, method: str) -> ComparisonResult | None:
        return next((r for r in self.results if r.method == method), None)


def write_report(
    directory: str | Path,
    scenes: Sequence[SceneEntry],
    *,
    title: str = "Pavonine render checks",
    display_width: int = 256,
) -> Path:
    """Write ``directory/index.html`` and its PNGs under ``directory/images``; return the page path."""
    import jinja2

    directory = Path(directory)
    images = directory / "images"
    images.mkdir(parents=True, exist_ok=True)
    for scene in scenes:
        stem = scene.anchor
        scene.images = {
            "render": f"images/{stem}-render.png",
            "baseline": f"images/{stem}-baseline.png",
        }
        write_png(directory / scene.images["render"], scene.render)
        write_png(directory / scene.images["baseline"], scene.baseline)
        for result in scene.results:
            scene.images[result.method] = f"images/{stem}-{result.method}-diff.png"
            write_display_png(directory / scene.images[result.method], result.heatmap)
    methods = sorted({r.method for s in scenes for r in s.results}, key=lambda m: (m != "stat", m))
    env = jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined)
    page = env.from_string(_TEMPLATE).render(
        title=title,
        created=_dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        scenes=list(scenes),
        methods=methods,
        all_passed=all(s.passed for s in scenes),
        display_width=display_width,
    )
    target = directory / "index.html"
    with atomic_path(target) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return target
