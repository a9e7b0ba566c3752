"use strict";
// Objects chosen by clicking them in the top view. A click on an object's shape (or on a liquid's name in its
// container's label) fills the next empty list of the form being filled: the step row last clicked or focused
// (the first row at first, or the row of a step just refused), or the task form. An object the list does not
// offer is not taken, and the message above the picture says why, by the object's name. A chosen object is
// highlighted; clicking it again empties its list. A click inside an object's shape means that object even where
// another's slanted label crosses it. Choosing another task empties and sets aside the lists it does not take.
// The lists stay as they are for the keyboard; without this script the page works as before.
(function () {
  var scene = document.getElementById("scene");
  var message = document.getElementById("pick-message");
  var forms = Array.prototype.slice.call(document.querySelectorAll("form[data-pick]"));
  if (!scene || !message || !forms.length) { return; }
  // a refused step's row comes back with its objects chosen, and is the one being filled
  var active = forms.filter(function (f) { return f.querySelector("option[selected]"); })[0] || forms[0];

  function lists(form) {
    return Array.prototype.slice.call(form.querySelectorAll("select[data-offers]"));
  }

  function offers(list, id) {
    return Array.prototype.some.call(list.options, function (o) { return o.value === id && id !== ""; });
  }

  function nameOf(list) {  // the chosen object's name, never its id
    var option = list.options[list.selectedIndex];
    return option ? option.getAttribute("data-name") || option.textContent : "";
  }

  function what(form) {  // the step or task as chosen so far, in names: place_above(cup, …)
    var names = form.hasAttribute("data-held") ? [form.getAttribute("data-held")] : [];
    lists(form).slice(0, room(form)).forEach(function (list) { names.push(list.value ? nameOf(list) : "…"); });
    return kind(form) + "(" + names.join(", ") + ")";
  }

  function kind(form) {  // the primitive, or the task chosen in the task form
    var task = form.querySelector("select[name=task]");
    return task ? task.value : form.getAttribute("data-pick");
  }

  function room(form) {  // how many lists a click may fill: a task's arity, else all of them
    var task = form.querySelector("select[name=task]");
    var n = task ? Number(task.options[task.selectedIndex].getAttribute("data-arity")) : NaN;
    return isNaN(n) ? lists(form).length : Math.min(n, lists(form).length);
  }

  function liquidTask(form) {
    var task = form.querySelector("select[name=task]");
    return task !== null && task.options[task.selectedIndex].hasAttribute("data-liquid");
  }

  function say(text) { message.textContent = text; }

  function progress(form) {  // what is chosen so far, and what to do next
    var rest = lists(form).slice(0, room(form)).some(function (l) { return l.value === ""; });
    return what(form) + (rest ? ": click the next object" : ": " + form.getAttribute("data-ready"));
  }

  function fit(form) {  // the task form's lists beyond the task's objects: emptied and left out of the form
    var n = room(form);
    lists(form).forEach(function (list, k) {
      if (k >= n) { list.value = ""; }
      list.disabled = k >= n;
    });
  }

  function show() {  // highlight the objects the active form has chosen, and the row being filled
    var chosen = lists(active).map(function (list) { return list.value; });
    Array.prototype.forEach.call(scene.querySelectorAll("[data-object]"), function (shape) {
      shape.classList.toggle("picked", chosen.indexOf(shape.getAttribute("data-object")) >= 0);
    });
    forms.forEach(function (form) {
      (form.closest("tr") || form).classList.toggle("picking", form === active && forms.length > 1);
    });
  }

  function pick(shape) {
    var id = shape.getAttribute("data-object");
    var name = shape.getAttribute("data-name");
    var all = lists(active);
    for (var k = all.length - 1; k >= 0; k--) {
      if (all[k].value === id) {  // chosen again: unselected
        all[k].value = "";
        show();
        say(name + " is unselected: " + what(active));
        return;
      }
    }
    var list = all.slice(0, room(active)).filter(function (l) { return l.value === ""; })[0];
    if (!list) {
      say(what(active) + " has its objects; click one of them to unselect it first");
    } else if (!offers(list, id)) {
      say(name + " is not offered for " + kind(active) + ": it takes " + list.getAttribute("data-offers"));
    } else if (list.name === "arg1" && liquidTask(active) && !shape.hasAttribute("data-liquid")) {
      var liquids = Array.prototype.map.call(shape.querySelectorAll("[data-liquid]"),
                                             function (l) { return l.getAttribute("data-name"); });
      say(kind(active) + " takes a liquid, not " + name + (liquids.length
          ? ": click " + liquids.join(" or ") + " in its label" : ": click a liquid's name in its container's label"));
    } else {
      list.value = id;
      show();
      say(progress(active));
    }
  }

  forms.forEach(function (form) {
    lists(form).forEach(function (list) {  // with the script a list starts empty, unless the page chose for it
      if (!list.querySelector("option[value='']")) {
        var none = !Array.prototype.some.call(list.options, function (o) { return o.defaultSelected; });
        var empty = new Option("(choose or click)", "");
        list.insertBefore(empty, list.firstChild);
        if (none) { list.value = ""; }
        list.required = true;
      }
      list.addEventListener("change", show);
    });
    var task = form.querySelector("select[name=task]");
    if (task) {  // another task: the lists it does not take are emptied, and the message says what is chosen now
      fit(form);
      task.addEventListener("change", function () { fit(form); show(); say(progress(form)); });
    }
    var row = form.closest("tr") || form;
    var choose = function () { if (active !== form) { active = form; show(); } };
    row.addEventListener("focusin", choose);
    row.addEventListener("click", choose);
  });
  scene.classList.add("pickable");
  function under(event) {  // the object whose shape is under the pointer, the topmost drawn; furniture aside
    var hit = null;
    Array.prototype.forEach.call(scene.querySelectorAll("g.object:not([data-kind=furniture]) > rect"), function (r) {
      var box = r.getBoundingClientRect();
      if (event.clientX >= box.left && event.clientX <= box.right &&
          event.clientY >= box.top && event.clientY <= box.bottom) { hit = r.parentNode; }
    });
    return hit;
  }
  function takes(form, shape) {  // whether the next list to fill would take the object
    var list = lists(form).slice(0, room(form)).filter(function (l) { return l.value === ""; })[0];
    return list !== undefined && offers(list, shape.getAttribute("data-object")) &&
      !(list.name === "arg1" && liquidTask(form) && !shape.hasAttribute("data-liquid"));
  }

  // A click inside an object's shape picks that object, even where another object's slanted label is drawn across
  // it, unless only the name under the pointer is one the list being filled takes (a liquid in its container's
  // label, for a liquid task); elsewhere (a label, furniture) what is under the pointer picks.
  scene.addEventListener("click", function (event) {
    var here = [under(event), event.target.closest("[data-object]")].filter(function (s) { return s; });
    var chosen = lists(active).map(function (list) { return list.value; });
    var again = here.filter(function (s) { return chosen.indexOf(s.getAttribute("data-object")) >= 0; });
    var taken = here.filter(function (s) { return takes(active, s); });
    var shape = again[0] || taken[0] || here[0];  // a chosen one unselects; else one the list takes; else the shape
    if (shape) { pick(shape); }
  });
  var hint = document.getElementById("pick-hint");
  if (hint) { hint.hidden = false; }
  show();
})();
