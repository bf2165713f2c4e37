// Replicates line motifs with the npm package `wallpaper-groups` (MIT, eskimoblood),
// an outside reference for `python -m bench vision` (source "npm-wallpaper-groups").
// Reads {"requests": [{type, width, height, columns, rows, lines}]} as JSON on stdin,
// writes per request the package's tile outline (`tile`) and the pattern's lines
// (`lines`, each a list of [x, y] points), in the package's order (line k of a tile is the image of input line
// k mod lines.length). The package is loaded from the directory given as argv[2]
// (its node_modules), installed there by `make bench`.
"use strict";
const path = require("path");

const root = process.argv[2];
const pkg = require(path.join(root, "node_modules", "wallpaper-groups"));
const wallpaper = pkg.default;  // an ES module compiled by Babel 5

let input = "";
process.stdin.on("data", (chunk) => { input += chunk; });
process.stdin.on("end", () => {
  const requests = JSON.parse(input).requests;
  const out = requests.map((r) => {
    const lines = r.lines.map((line) => line.map(([x, y]) => ({ x, y })));
    const tiles = wallpaper({ ...r, lines });
    const tile = pkg.getTile(r.type, r.width, r.height).map((p) => [p.x, p.y]);
    return { tile, lines: tiles.flat().map((line) => line.map((p) => [p.x, p.y])) };
  });
  process.stdout.write(JSON.stringify({ types: pkg.patternTypes, patterns: out }));
});
