"""The ground floor: the plumbing every room of Pavonine uses, importing nothing above it.

One-line input errors (:mod:`.errors`), atomic and journalled writes (:mod:`.commit`), checks
that a file was not cut short (:mod:`.truncation`, :mod:`.groups`), input limits
(:mod:`.limits`), map and image file formats (:mod:`.map_files`, :mod:`.image_files`), files
inside USD packages (:mod:`.asset_io`), the Mitsuba variant (:mod:`.backend`), USD's plugin
registration hook (:mod:`.usd_import`), Ctrl-C (:mod:`.interrupt`), native libraries' output
(:mod:`.native_output`), the shipped data (:mod:`.shipped`) and fault injection for tests
(:mod:`.faults`). docs/house.md draws the floors.
"""
