"""An HTML template for `dvc plots show` that draws its plots with no network.

DVC's own page loads Vega, Vega-Lite and Vega-Embed from a CDN, so offline
(or behind a firewall) it stays blank. This template holds those libraries
inline, from vl-convert's bundle of them, and leaves out DVC's `{scripts}`
placeholder, where the CDN links would go; `.dvc/config` names it
(`plots.html_template`), so `dvc plots show` and `dvc plots diff` use it.
"""

from __future__ import annotations

PAGE = """<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
{refresh_tag}
<title>taskseq plots</title>
<script>
BUNDLE
</script>
<style>
body { font-family: sans-serif; margin: 1.5em; }
table { border-spacing: 15px; }
</style>
</head>
<body>
{plot_divs}
</body>
</html>
"""


def offline_template() -> str:
    """The page, with Vega, Vega-Lite and Vega-Embed inline (about 0.9 MB); the same bytes for one vl-convert."""
    import vl_convert

    bundle = vl_convert.javascript_bundle()
    if "</script" in bundle.lower():  # would end the script element early
        raise RuntimeError("the Vega bundle holds '</script'; it cannot be inlined")
    return PAGE.replace("BUNDLE", bundle)
