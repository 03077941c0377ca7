// Injected after the viewer's script by screenshot.sh: drives the controls with synthetic
// events and writes what changed into <body data-test>, which `chromium --dump-dom` prints.
// Each step checks the effect of the previous one's events, then sends its own.
window.addEventListener("load", function () {
  "use strict";
  var c = document.getElementById("view"), body = document.body, log = [];
  function state() { return body.getAttribute("data-state").split(","); }
  function frame() { return +body.getAttribute("data-frame"); }
  function key(k, shift) {
    window.dispatchEvent(new KeyboardEvent("keydown", { key: k, shiftKey: !!shift, bubbles: true }));
  }
  function pointer(type, x, y, button, shift) {
    c.dispatchEvent(new PointerEvent(type, { pointerId: 7, button: button || 0, shiftKey: !!shift,
      clientX: x, clientY: y, bubbles: true }));
  }
  function check(name, ok) { log.push((ok ? "ok " : "FAIL ") + name); }
  var steps = [
    function () {
      steps.initial = state();
      check("starts playing", state()[0] === "playing");
      // The motions are named by their files (issue 18), not "trajectory" and "compared".
      var legend = document.querySelector(".legend").textContent;
      check("the legend names the files",
            legend.indexOf("A \u00b7 cloth.npy (solid)") >= 0 &&
            legend.indexOf("B \u00b7 cloth_b.npy (dashed, pale)") >= 0);
      // ... and it never covers a panel: the scene is drawn left of it.
      var right = +body.getAttribute("data-scene-right");
      check("the scene is drawn left of the legend (" + right + " px)", right > 0 &&
            right <= document.querySelector(".legend").getBoundingClientRect().left);
      // ... and below the info panel, which never covers it either.
      var top = +body.getAttribute("data-scene-top");
      check("the scene is drawn below the info panel (" + top + " px)", top > 0 &&
            top >= document.querySelector(".info").getBoundingClientRect().bottom);
      // The PNG button downloads the current frame: catch the link it clicks.
      var clicked = null, click = HTMLAnchorElement.prototype.click;
      HTMLAnchorElement.prototype.click = function () { clicked = this; };
      document.querySelector(".controls .png").click();
      HTMLAnchorElement.prototype.click = click;
      if (clicked) body.setAttribute("data-png", clicked.href);
      check("PNG export (" + (clicked ? clicked.download + ", " + clicked.href.length + " chars" : "none") + ")",
            !!clicked && clicked.href.indexOf("data:image/png;base64,") === 0 &&
            clicked.href.length > 20000 && /-frame\d+\.png$/.test(clicked.download));
      key(" ");
    },
    function () {
      check("space pauses", state()[0] === "paused");
      key("Home"); key("ArrowRight"); key("ArrowRight"); key("ArrowRight", true);
    },
    function () {
      check("arrows step (12 = " + frame() + ")", frame() === 12);
      steps.before = state();
      pointer("pointerdown", 500, 300); pointer("pointermove", 560, 330); pointer("pointerup", 560, 330);
    },
    function () {
      var s = state(), b = steps.before;
      check("drag orbits", s[3] !== b[3] && s[4] !== b[4] && s[6] === b[6]);
      steps.before = s;
      pointer("pointerdown", 500, 300, 0, true); pointer("pointermove", 540, 300); pointer("pointerup", 540, 300);
    },
    function () {
      var s = state(), b = steps.before;
      check("shift-drag pans", s[6] !== b[6] && s[3] === b[3]);
      steps.before = s;
      c.dispatchEvent(new WheelEvent("wheel", { deltaY: 300, bubbles: true, cancelable: true }));
    },
    function () {
      var s = state(), b = steps.before;
      check("wheel down zooms out", +s[5] > +b[5]);
      key("r");
    },
    function () {
      var s = state(), a = steps.initial;
      check("R resets the view", [3, 4, 5, 6].every(function (k) { return s[k] === a[k]; }));
      key("End");
    },
    function () {
      check("End goes to the last frame", frame() === +document.querySelector(".slider").max);
      var btn = document.querySelector(".controls .play");
      btn.click();
    },
    function () {
      check("the button plays from the start", state()[0] === "playing");
      key("s");
    },
    function () {
      var hasB = document.querySelectorAll(".segmented button").length === 2;
      check("S switches to side by side", !hasB || state()[1] === "side");
      var sel = document.querySelector(".speed");
      sel.value = "2";
      sel.dispatchEvent(new Event("change"));
    },
    function () { check("speed menu", state()[2] === "2"); }
  ];
  // The page publishes its state as soon as it changes: the steps run one after the other.
  // (Headless Chromium runs animation frames only now and then, so nothing waits for one.)
  for (var i = 0; i < steps.length; i++) {
    try {
      steps[i].call(steps);
    } catch (err) {
      log.push("FAIL step " + i + ": " + err);
    }
  }
  body.setAttribute("data-test", log.join("; "));
});
