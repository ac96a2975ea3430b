// The studio's latent map as a Plotly figure. explorer/latent_panel.py sends the points (`latent_points`), the
// current sequence's ring and the current mix's star (`latent_marks`) and the colouring (`latent_color`) through
// trame's state; the layout calls immLatent.draw / immLatent.marks when they change. A click on a point asks the
// server to open and play it (trigger `latent_pick`); a box or lasso selection sets `latent_selection`.
//
// plotly.js (its basic bundle, 1.2 MB: explorer/static/vendor/README.md) is fetched (into the browser's cache) once the
// 3D view shows its first picture, so the page opens as fast as it does without it (benchmarks/explorer_startup.py),
// and evaluated once the user has not pressed a key, clicked or dragged for QUIET_MS, however long that takes:
// evaluating it holds the page's thread (0.3-0.5 s on 2 cores; the full bundle up to two seconds), and a slider moved
// meanwhile showed its picture that much later (benchmarks/explorer_latency.py, the first changes).
// The launcher serves it for every tab at one path above the tab's /s/<id>/ (a reverse proxy's prefix kept: the path
// is relative), so the browser's cache serves a second tab; explorer/serving/page_shell.py puts plotly.js's version
// into its name.
(() => {
  const PLOTLY_SRC = '../../static/plotly.min.js';  // explorer/serving/launcher.py, `static`
  const VIEW_IMG = '.imm-scene img';
  const PLOT_ID = 'latent-plotly';
  const FIRST_PICTURE_WAIT_MS = 8000;  // load it anyway after this long (a page with no picture still gets its map)
  const QUIET_MS = 1000;  // ... and evaluate it after this long without a key, click or drag
  // The star (the current mix) moves once keys, clicks and drags have rested this long, the latest marks only: moving
  // it redraws the figure, 50-100 ms of the page's thread on 2 cores, which held back the next slider move's state
  // (docs/experiments/studio-performance.md)
  const MARKS_QUIET_MS = 400;
  let lastInput = performance.now();
  for (const type of ['keydown', 'pointerdown', 'pointermove', 'wheel', 'input']) {
    document.addEventListener(type, (e) => {
      if (type !== 'pointermove' || e.buttons) lastInput = performance.now();
    }, {capture: true, passive: true});
  }
  let loading = null;
  let plotted = null;  // the element the figure lives in
  let last = {points: null, marks: null, mode: 'class', colors: null};
  let marksDue = null;  // the star's move waiting for a pause (a promise), or null

  function until(ready) {  // resolves at the first 50 ms poll at which ready() holds
    return new Promise((resolve) => {
      const poll = () => (ready() ? resolve() : setTimeout(poll, 50));
      poll();
    });
  }

  function whenQuiet(quietMs) {
    return until(() => performance.now() - lastInput >= quietMs);
  }

  function firstPicture() {  // the 3D view's first picture shown, or FIRST_PICTURE_WAIT_MS passed without one
    const start = performance.now();
    return until(() => {
      const img = document.querySelector(VIEW_IMG);
      return (img && img.complete && img.naturalWidth > 100) || performance.now() - start > FIRST_PICTURE_WAIT_MS;
    });
  }

  function plotly() {
    if (!loading) {
      loading = firstPicture().then(() => {
        fetch(PLOTLY_SRC).then((r) => r.blob()).catch(() => {});  // into the cache: the script below takes it there
        return whenQuiet(QUIET_MS);
      }).then(() => new Promise((resolve, reject) => {
        const script = document.createElement('script');
        script.src = PLOTLY_SRC;
        script.async = true;
        script.onload = () => resolve(window.Plotly);
        script.onerror = () => reject(new Error('the latent map could not load plotly.js'));
        document.head.appendChild(script);
      }));
    }
    return loading;
  }

  function hoverRow(p, i) {
    return [i, p.id[i], p.class_names[p.cls[i]], p.pair[i], p.held[i] ? 'held out' : 'seen in training',
            p.afd ? p.afd[i].toFixed(3) : '(computing)'];
  }

  const HOVER = '<b>%{customdata[1]}</b><br>%{customdata[2]} · subjects %{customdata[3]}<br>%{customdata[4]}'
    + ' · AFD %{customdata[5]}<extra></extra>';

  function group(p, name, members, marker) {
    return {type: 'scatter', mode: 'markers', name, meta: 'points', hovertemplate: HOVER,
            x: members.map((i) => p.x[i]), y: members.map((i) => p.y[i]),
            customdata: members.map((i) => hoverRow(p, i)), marker: {size: 9, ...marker}};
  }

  function mark(name, meta, xy, marker) {
    return {type: 'scatter', mode: 'markers', name, meta, hoverinfo: 'skip', x: xy ? [xy[0]] : [], y: xy ? [xy[1]] : [],
            marker};
  }

  function traces(p, marks, mode, colors) {
    const all = p.x.map((_, i) => i);
    const symbols = (members) => members.map((i) => (p.held[i] ? 'circle-open' : 'circle'));
    let points;
    if (mode === 'afd' && p.afd) {
      points = [group(p, 'AFD', all, {color: all.map((i) => p.afd[i]), colorscale: 'Viridis', showscale: true,
                                      symbol: symbols(all), line: {width: 2},
                                      colorbar: COLORBAR})];
      points[0].showlegend = false;
    } else if (mode === 'held') {
      points = [group(p, 'seen in training', all.filter((i) => !p.held[i]), {color: '#78909c'}),
                group(p, 'held out', all.filter((i) => p.held[i]), {color: '#ff8f00'})];
    } else {
      points = p.class_names.map((name, c) => {
        const members = all.filter((i) => p.cls[i] === c);
        return group(p, name, members, {color: colors.classes[c], symbol: symbols(members), line: {width: 2, color: colors.classes[c]}});
      });
    }
    return points.concat([
      mark('this sequence', 'ring', marks && marks.ring, {size: 17, symbol: 'circle-open', color: '#111', line: {width: 2.5}}),
      mark('current mix', 'star', marks && marks.star, {size: 17, symbol: 'star', color: colors.star, line: {width: 1, color: '#111'}}),
    ]);
  }

  // The AFD colour bar shares the right-hand column with the legend (its two marks): the legend at the top, the bar
  // under it, its title beside it rather than on top, where it sat on the "current mix" entry.
  const COLORBAR = {title: {text: 'AFD', side: 'right'}, thickness: 10, len: 0.62, lenmode: 'fraction', y: 0, yanchor: 'bottom'};

  // The tool bar stands upright in a left margin of its own (CSS in explorer/ui/layout.py moves it there): at the top
  // right, Plotly's place for it, it covered the legend's first entries whenever the mouse was over the map.
  function layout(p) {
    const axis = {showticklabels: false, zeroline: false, showgrid: true, gridcolor: '#eee'};
    return {uirevision: p.method, margin: {l: 30, r: 4, t: 4, b: 8}, hovermode: 'closest', dragmode: 'zoom', font: {size: 10},
            xaxis: axis, yaxis: {...axis}, legend: {font: {size: 10}, itemsizing: 'constant', y: 1, yanchor: 'top'},
            modebar: {orientation: 'v'}, autosize: true};
  }

  // Nothing on the map sends the figure anywhere: plotly.js v4 shows a "Share chart..." button (sendChartToCloud, an
  // upload of every point's id, class and subjects to Chart Studio) unless told not to; tests/test_studio_offline.py.
  const CONFIG = {displaylogo: false, responsive: true, scrollZoom: true, showSendToCloud: false, showEditInChartStudio: false,
                  showLink: false, plotlyServerURL: '',
                  modeBarButtonsToRemove: ['toImage', 'sendChartToCloud', 'sendDataToCloud', 'editInChartStudio', 'autoScale2d',
                                           'hoverClosestCartesian', 'hoverCompareCartesian', 'zoomIn2d', 'zoomOut2d']};  // the wheel zooms

  function listen(el) {
    el.on('plotly_click', (e) => {
      const pt = e.points.find((q) => q.data.meta === 'points');
      if (pt) window.trame.trigger('latent_pick', [pt.customdata[0]]);
    });
    el.on('plotly_selected', (e) => {
      const picked = e ? e.points.filter((q) => q.data.meta === 'points').map((q) => q.customdata[0]) : [];
      window.trame.state.set('latent_selection', picked);
    });
    el.on('plotly_deselect', () => window.trame.state.set('latent_selection', []));
    new ResizeObserver(() => window.Plotly.Plots.resize(el)).observe(el);
  }

  async function render() {
    const Plotly = await plotly();  // loading starts after the first picture even while a cold map is still fitted
    const {points, marks, mode, colors} = last;  // the latest, once plotly.js is there
    if (!points || !colors) return;
    const el = document.getElementById(PLOT_ID);
    if (!el) return;
    await Plotly.react(el, traces(points, marks, mode, colors), layout(points), CONFIG);
    if (plotted !== el) {
      plotted = el;
      listen(el);
    }
    el.dataset.method = points.method;
    el.dataset.mode = mode;
  }

  async function moveMarks() {
    const el = plotted;
    if (!el || !el.data || document.getElementById(PLOT_ID) !== el) return render();
    const {marks} = last;
    const at = (meta) => el.data.findIndex((t) => t.meta === meta);
    const xy = (m) => (m ? [[m[0]], [m[1]]] : [[], []]);
    const [ring, star] = [xy(marks && marks.ring), xy(marks && marks.star)];
    return window.Plotly.restyle(el, {x: [ring[0], star[0]], y: [ring[1], star[1]]}, [at('ring'), at('star')]);
  }

  window.immLatent = {
    draw(points, marks, mode, colors) {
      last = {points, marks, mode: mode || 'class', colors};
      return render().catch((err) => window.trame.state.set('error', String(err.message || err)));
    },
    marks(marks) {
      last.marks = marks;  // a move already waiting takes these
      if (!marksDue) {
        marksDue = whenQuiet(MARKS_QUIET_MS).then(() => {
          marksDue = null;
          return (plotted ? moveMarks() : render()).catch(() => {});
        });
      }
      return marksDue;
    },
  };
})();
