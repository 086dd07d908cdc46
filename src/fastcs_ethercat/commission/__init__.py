"""`fastcs-ethercat init`: from a rack to the files of a running IOC.

One module per step, each usable alone:

- `rack`: what the rack runs, as chain entries (`RackSlave`), and what
  changed between two chains (`rack_changes`);
- `sources`: the terminal YAML for each type and revision on the rack
  (already in DIR, shipped, or generated from the ESI);
- `choices`: the PDO group and oversampling factor the rack runs, selected
  in that YAML;
- `layout`: the files of DIR (ioc.yaml, the services-repo instance), written
  in a folder beside DIR and moved into place;
- `writing`: what goes into that folder (the YAML with the running group,
  the chain, the configs, the instance);
- `served`: what the IOC of DIR serves (PVs, screens, PV lists);
- `run`: the steps in order, and the summary.
"""
