// The theme: #theme=light|dark in the address, else the system's; the button flips it.
(function () {
  "use strict";
  var root = document.documentElement;
  var m = /theme=(light|dark)/.exec(location.hash);
  if (m) root.setAttribute("data-theme", m[1]);
  document.getElementById("theme").addEventListener("click", function () {
    var dark = root.getAttribute("data-theme") === "dark" ||
      (!root.getAttribute("data-theme") && matchMedia("(prefers-color-scheme: dark)").matches);
    root.setAttribute("data-theme", dark ? "light" : "dark");
  });
})();
