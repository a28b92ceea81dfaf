#!/usr/bin/env python3
"""Checks deploy/kubernetes and deploy/docker/Dockerfile against Kubernetes,
against each other and against the programs they run:

  python3 tests/deploy/check_kubernetes.py --server-bin build/bin/reenact-server \
      --worker-bin build/bin/reenact-worker [--cli-bin build/bin/reenact] \
      [--manifests DIR] [--dockerfile FILE] [--dockerignore FILE] [--skip-flag-check] \
      [--skip-kubectl]

- every manifest parses, each object has an apiVersion/kind that Kubernetes
  1.27+ serves and a string metadata.name; kustomization.yaml lists exactly
  the manifests of the folder and its images entry names the image they run;
- each Deployment/StatefulSet: its selector matches its pod labels, every
  volumeMount names a declared volume and every volume is mounted, every
  probe's port is a declared containerPort, no gRPC probe on a TLS port (the
  kubelet's probe dials without TLS), runAsUser is the Dockerfile's uid;
- each Service selects a workload and its targetPorts name or number one of
  that workload's containerPorts;
- each StatefulSet's serviceName is a Service of the folder that is headless
  (clusterIP: None) and selects the StatefulSet's pods, as Kubernetes wants
  of a StatefulSet's governing Service;
- the HorizontalPodAutoscaler scales a Deployment of the folder that runs
  reenact-worker, and its External metrics are gauges reenact-server exports;
- every --flag of a container that runs a Reenact program is in that
  program's --help (the programs come as arguments), and --insecure on
  reenact-server comes with TLS and tokens;
- the Dockerfile's stages are Debian 12 (bookworm), the last one
  debian:bookworm-slim with a non-root USER, and it installs every program
  the manifests run into a bin folder (and the web app where the server
  looks for it); it copies the tracker's models that CMakeLists.txt's
  install() rule installs (models/tracker) to PREFIX/share/reenact/models/
  tracker beside the bin folder of reenact, where the installed programs
  look for them, and after that a RUN of the last stage runs the installed
  `reenact track` (no --model, no $REENACT_TRACKER_MODEL, no `|| true`), so
  that the image build fails when the model is not where it looks;
- .dockerignore: the build context leaves out the secrets and data the
  README's commands write into the checkout (tls/ and certs/ of
  deploy/make-certs.sh, *.key, *.pem, *.token, tokens.json, takes *.mcap,
  reenactments *.reen, exports *.glb/*.bvh/*.mp4, stores' *.sqlite, reports,
  frames), tried on sample paths (IGNORED_SAMPLES), and leaves in everything
  the Dockerfile copies from the context: each COPY/ADD source exists, and
  no file of it that git tracks (for `COPY . .`: every tracked file) is left
  out. Patterns are matched as Docker's moby/patternmatcher does (one regular
  expression per pattern: * and ? stop at "/", **/ is any number of folders,
  a path is left out when it or a folder above it matches, the last matching
  pattern deciding, ! patterns taking back); Docker's quirks beyond that
  (e.g. escapes on Windows) are not modelled. Without git only the COPY
  sources themselves are tried;
- with kubectl on PATH: `kubectl kustomize` builds the folder (offline), then
  `kubectl apply --dry-run=client -k`, skipped loudly where that needs an API
  server.

Prints what it checked; exits 1 naming the file and field of each problem,
77 (skipped) without python3-yaml (Debian: python3-yaml,
deploy/setup-debian.sh installs it).
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys

try:
    import yaml
except ImportError:
    print("SKIPPED: python3-yaml is not installed (apt-get install python3-yaml, "
          "or deploy/setup-debian.sh)")
    sys.exit(77)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# apiVersion -> kinds that Kubernetes 1.27 and later serve (the ones a
# deployment of Reenact could use; add a CRD's here when one is installed).
SERVED = {
    "v1": {"Namespace", "Service", "ConfigMap", "Secret", "PersistentVolumeClaim",
           "ServiceAccount", "Pod", "LimitRange", "ResourceQuota"},
    "apps/v1": {"Deployment", "StatefulSet", "DaemonSet", "ReplicaSet"},
    "autoscaling/v1": {"HorizontalPodAutoscaler"},
    "autoscaling/v2": {"HorizontalPodAutoscaler"},
    "policy/v1": {"PodDisruptionBudget"},
    "batch/v1": {"Job", "CronJob"},
    "networking.k8s.io/v1": {"NetworkPolicy", "Ingress", "IngressClass"},
    "rbac.authorization.k8s.io/v1": {"Role", "RoleBinding", "ClusterRole",
                                     "ClusterRoleBinding"},
    "scheduling.k8s.io/v1": {"PriorityClass"},
}
# API versions gone by 1.27, and the release that stopped serving them.
REMOVED = {
    "extensions/v1beta1": "1.22", "apps/v1beta1": "1.16", "apps/v1beta2": "1.16",
    "networking.k8s.io/v1beta1": "1.22", "autoscaling/v2beta1": "1.25",
    "autoscaling/v2beta2": "1.26", "policy/v1beta1": "1.25", "batch/v1beta1": "1.25",
}
WORKLOADS = {"Deployment", "StatefulSet"}
PROGRAMS = ("reenact-server", "reenact-worker", "reenact")

problems = []


class KubeLoader(yaml.SafeLoader):
    """PyYAML's safe loader, reading y/Y/n/N as booleans as Kubernetes' YAML
    reader does, so that an unquoted one is caught where a string belongs."""


KubeLoader.add_implicit_resolver("tag:yaml.org,2002:bool", re.compile(r"^(?:y|Y|n|N)$"),
                                 list("yYnN"))
KubeLoader.add_constructor("tag:yaml.org,2002:bool",
                           lambda loader, node: loader.construct_scalar(node) in
                           ("y", "Y", "yes", "Yes", "YES", "true", "True", "TRUE",
                            "on", "On", "ON"))


def fail(where, message):
    problems.append(f"{where}: {message}")
    print(f"FAIL {where}: {message}")


def ok(message):
    print(f"ok   {message}")


# --- manifests ---------------------------------------------------------------

def load_manifests(folder):
    """[(file, object)] of every YAML file but kustomization.yaml, and the
    kustomization (or None)."""
    objects, kustomization = [], None
    names = sorted(n for n in os.listdir(folder) if n.endswith((".yaml", ".yml")))
    if not names:
        fail(folder, "no manifests")
    for name in names:
        path = os.path.join(folder, name)
        try:
            with open(path, encoding="utf-8") as f:
                documents = [d for d in yaml.load_all(f, Loader=KubeLoader) if d is not None]
        except yaml.YAMLError as e:
            fail(name, f"does not parse: {e}")
            continue
        for i, doc in enumerate(documents):
            where = f"{name} (document {i + 1})"
            if not isinstance(doc, dict):
                fail(where, "is not a mapping")
                continue
            if name in ("kustomization.yaml", "kustomization.yml"):
                kustomization = (name, doc)
                continue
            objects.append((name, doc))
        ok(f"{name}: parses ({len(documents)} document(s))")
    return objects, kustomization


def ident(obj):
    return f"{obj.get('kind')}/{(obj.get('metadata') or {}).get('name')}"


def check_api(name, obj):
    api, kind = obj.get("apiVersion"), obj.get("kind")
    meta = obj.get("metadata") or {}
    if not isinstance(meta.get("name"), str) or not meta.get("name"):
        # YAML 1.1 reads y, no, on... as booleans: quote such names.
        fail(f"{name} {kind}", f"metadata.name must be a string, got {meta.get('name')!r}")
        return False
    for field, meta_of in (("metadata", meta),
                           ("spec.template.metadata",
                            ((obj.get("spec") or {}).get("template") or {}).get("metadata") or {})):
        for kind_of in ("labels", "annotations"):
            for key, value in (meta_of.get(kind_of) or {}).items():
                if not isinstance(value, str):
                    fail(f"{name} {ident(obj)}", f"{field}.{kind_of}.{key} must be a string "
                         f"(quote it), got {value!r}")
    if api in REMOVED:
        fail(f"{name} {ident(obj)}", f"apiVersion {api} is no longer served "
             f"(removed in Kubernetes {REMOVED[api]})")
        return False
    if kind not in SERVED.get(api, ()):
        fail(f"{name} {ident(obj)}", f"apiVersion/kind {api}/{kind} is not one Kubernetes "
             "1.27+ serves (tests/deploy/check_kubernetes.py SERVED lists them)")
        return False
    ok(f"{name} {ident(obj)}: {api} {kind} is served by Kubernetes 1.27+")
    return True


def selector_matches(selector, labels):
    labels = labels or {}
    for key, value in (selector.get("matchLabels") or {}).items():
        if labels.get(key) != value:
            return False
    for expression in selector.get("matchExpressions") or []:
        key, op = expression.get("key"), expression.get("operator")
        values = expression.get("values") or []
        if op == "In" and labels.get(key) not in values:
            return False
        if op == "NotIn" and labels.get(key) in values:
            return False
        if op == "Exists" and key not in labels:
            return False
        if op == "DoesNotExist" and key in labels:
            return False
    return True


def pod_spec(obj):
    return (((obj.get("spec") or {}).get("template") or {}).get("spec")) or {}


def containers(obj):
    """(field, container) of the init containers and containers."""
    spec = pod_spec(obj)
    for field in ("initContainers", "containers"):
        for c in spec.get(field) or []:
            yield f"{field}[{c.get('name')}]", c


def program_of(container):
    command = container.get("command") or []
    return os.path.basename(str(command[0])) if command else None


def container_flags(container):
    tokens = [str(t) for t in (container.get("command") or [])[1:]]
    tokens += [str(t) for t in container.get("args") or []]
    return [t.split("=", 1)[0] for t in tokens if t.startswith("--") and len(t) > 2]


def check_workload(name, obj, dockerfile_uid):
    where = f"{name} {ident(obj)}"
    spec = obj.get("spec") or {}
    template = spec.get("template") or {}
    labels = (template.get("metadata") or {}).get("labels") or {}
    selector = spec.get("selector") or {}
    if not selector.get("matchLabels") and not selector.get("matchExpressions"):
        fail(where, "spec.selector is empty")
    elif not selector_matches(selector, labels):
        fail(where, f"spec.selector {selector} does not match "
             f"spec.template.metadata.labels {labels}")
    else:
        ok(f"{where}: spec.selector matches the pod template's labels")

    podspec = pod_spec(obj)
    volumes = {v.get("name") for v in podspec.get("volumes") or []}
    if obj.get("kind") == "StatefulSet":
        volumes |= {(t.get("metadata") or {}).get("name")
                    for t in spec.get("volumeClaimTemplates") or []}
    mounted = set()
    ports = []  # (name, number) of every containerPort
    for field, c in containers(obj):
        for m in c.get("volumeMounts") or []:
            mounted.add(m.get("name"))
            if m.get("name") not in volumes:
                fail(where, f"spec.template.spec.{field}.volumeMounts[{m.get('name')}] "
                     f"names no declared volume (declared: {sorted(volumes)})")
        for p in c.get("ports") or []:
            ports.append((p.get("name"), p.get("containerPort")))
    for v in sorted(volumes - mounted):
        fail(where, f"volume {v} is declared but no container mounts it")
    if volumes <= mounted:
        ok(f"{where}: volumeMounts and volumes agree ({', '.join(sorted(volumes))})")

    for field, c in containers(obj):
        tls = "--tls-cert" in container_flags(c)
        for probe_name in ("startupProbe", "readinessProbe", "livenessProbe"):
            probe = c.get(probe_name)
            if not probe:
                continue
            for kind in ("tcpSocket", "httpGet", "grpc"):
                if kind not in probe:
                    continue
                port = probe[kind].get("port")
                if not any(port in (n, number) for n, number in ports):
                    fail(where, f"{field}.{probe_name}.{kind}.port {port!r} is not a "
                         "declared containerPort")
                elif kind == "grpc" and tls:
                    fail(where, f"{field}.{probe_name}.grpc: the kubelet's gRPC probe dials "
                         "without TLS, and this container serves gRPC with --tls-cert")
                else:
                    ok(f"{where}: {field}.{probe_name} {kind} port {port}")
    user = (podspec.get("securityContext") or {}).get("runAsUser")
    if user is not None and dockerfile_uid is not None and user != dockerfile_uid:
        fail(where, f"spec.template.spec.securityContext.runAsUser {user} is not the "
             f"image's user {dockerfile_uid} (deploy/docker/Dockerfile)")
    elif user is not None and dockerfile_uid is not None:
        ok(f"{where}: runAsUser {user} is the image's user")
    return labels, ports


def check_service(name, obj, workloads):
    where = f"{name} {ident(obj)}"
    selector = (obj.get("spec") or {}).get("selector") or {}
    selected = [w for w in workloads if selector and
                all(w["labels"].get(k) == v for k, v in selector.items())]
    if not selected:
        fail(where, f"spec.selector {selector} selects no Deployment/StatefulSet here")
        return
    declared = [p for w in selected for p in w["ports"]]
    for port in (obj.get("spec") or {}).get("ports") or []:
        target = port.get("targetPort", port.get("port"))
        if any(target in (n, number) for n, number in declared):
            ok(f"{where}: port {port.get('name')} -> targetPort {target} "
               f"({', '.join(w['id'] for w in selected)})")
        else:
            fail(where, f"spec.ports[{port.get('name')}].targetPort {target!r} is no "
                 f"containerPort of {', '.join(w['id'] for w in selected)} "
                 f"(declared: {declared})")


def check_governing_services(objects):
    """Each StatefulSet's serviceName: a headless Service of the folder that
    selects the StatefulSet's pods (Kubernetes makes the pods' DNS names
    through it; a Service with a cluster IP gives them none)."""
    services = {(o.get("metadata") or {}).get("name"): (n, o) for n, o in objects
                if o.get("kind") == "Service"}
    for name, obj in objects:
        if obj.get("kind") != "StatefulSet":
            continue
        where = f"{name} {ident(obj)}"
        spec = obj.get("spec") or {}
        service_name = spec.get("serviceName")
        labels = ((spec.get("template") or {}).get("metadata") or {}).get("labels") or {}
        if not service_name:
            fail(where, "spec.serviceName is missing: a StatefulSet needs a headless "
                 "governing Service")
            continue
        if service_name not in services:
            fail(where, f"spec.serviceName {service_name!r} names no Service of these "
                 "manifests")
            continue
        service_file, service = services[service_name]
        service_spec = service.get("spec") or {}
        selector = service_spec.get("selector") or {}
        problems_before = len(problems)
        if service_spec.get("clusterIP") != "None":
            fail(where, f"spec.serviceName {service_name!r} is not headless: "
                 f"{service_file} Service/{service_name} has clusterIP "
                 f"{service_spec.get('clusterIP', '(unset: one is allocated)')!r}, "
                 "a StatefulSet's governing Service needs clusterIP: None")
        if not selector or not all(labels.get(k) == v for k, v in selector.items()):
            fail(where, f"spec.serviceName {service_name!r}: its selector {selector} does "
                 f"not select the StatefulSet's pods (labels {labels})")
        if len(problems) == problems_before:
            ok(f"{where}: governed by the headless Service/{service_name} "
               f"({service_file}), which selects its pods")


def check_hpa(name, obj, workloads, server_bin):
    where = f"{name} {ident(obj)}"
    spec = obj.get("spec") or {}
    ref = spec.get("scaleTargetRef") or {}
    target = next((w for w in workloads if w["kind"] == ref.get("kind")
                   and w["name"] == ref.get("name")), None)
    if target is None or ref.get("apiVersion") != "apps/v1":
        fail(where, f"spec.scaleTargetRef {ref} names no apps/v1 workload of these manifests")
    elif target["kind"] != "Deployment" or "reenact-worker" not in target["programs"]:
        fail(where, f"spec.scaleTargetRef {ref} is not the Deployment that runs reenact-worker")
    else:
        ok(f"{where}: scales {target['id']}, which runs reenact-worker")
    low, high = spec.get("minReplicas", 1), spec.get("maxReplicas")
    if not isinstance(high, int) or high < low:
        fail(where, f"spec.maxReplicas {high!r} must be a number >= minReplicas {low}")
    names = [((m.get("external") or {}).get("metric") or {}).get("name")
             for m in spec.get("metrics") or [] if m.get("type") == "External"]
    if "reenact_job_queue_length" not in names:
        fail(where, "spec.metrics has no External metric reenact_job_queue_length")
    if server_bin:
        with open(server_bin, "rb") as f:
            binary = f.read()
        for metric in names:
            # Whole names only: reenact_jobs must not match reenact_jobs_total.
            bounded = rb"(?<![A-Za-z0-9_])" + re.escape(str(metric).encode()) + rb"(?![A-Za-z0-9_])"
            if metric and re.search(bounded, binary):
                ok(f"{where}: External metric {metric} is a gauge of reenact-server")
            else:
                fail(where, f"spec.metrics External {metric!r} is not exported by "
                     f"reenact-server ({server_bin})")
    else:
        print(f"note {where}: metric names not checked against reenact-server (no --server-bin)")


def check_kustomization(folder, kustomization, objects):
    if kustomization is None:
        fail(folder, "no kustomization.yaml")
        return
    name, doc = kustomization
    if (doc.get("apiVersion"), doc.get("kind")) != ("kustomize.config.k8s.io/v1beta1",
                                                    "Kustomization"):
        fail(name, "apiVersion/kind must be kustomize.config.k8s.io/v1beta1 Kustomization")
    listed = list(doc.get("resources") or [])
    files = sorted({f for f, _ in objects})
    for f in listed:
        if not os.path.isfile(os.path.join(folder, f)):
            fail(name, f"resources lists {f}, which does not exist")
    for f in files:
        if f not in listed:
            fail(name, f"resources does not list {f}")
    if set(listed) == set(files):
        ok(f"{name}: resources lists every manifest ({', '.join(listed)})")
    images = {i.get("name") for i in doc.get("images") or []}
    used = {re.split(r"[:@]", str(c.get("image")))[0] for _, o in objects
            if o.get("kind") in WORKLOADS for _, c in containers(o)}
    for image in sorted(used - images) if images else []:
        fail(name, f"images does not name {image}, which the workloads run")
    if images and used <= images:
        ok(f"{name}: images rewrites {', '.join(sorted(used))}")


# --- programs ----------------------------------------------------------------

def help_flags(binary):
    try:
        run = subprocess.run([binary, "--help"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as e:
        fail(binary, f"cannot run --help: {e}")
        return None
    return set(re.findall(r"(?<![\w-])(--[a-z0-9][a-z0-9-]*)", run.stdout + run.stderr))


def check_flags(objects, binaries):
    cache = {}
    for name, obj in objects:
        if obj.get("kind") not in WORKLOADS:
            continue
        for field, c in containers(obj):
            where = f"{name} {ident(obj)}"
            program = program_of(c)
            if program is None:
                fail(where, f"{field}.command is missing (the image's default command "
                     "only prints usage)")
                continue
            if program not in PROGRAMS:
                print(f"note {where}: {field} runs {program}, not a Reenact program: "
                      "flags not checked")
                continue
            binary = binaries.get(program)
            if not binary:
                fail(where, f"{field} runs {program}, but no path to it was given "
                     "(--server-bin/--worker-bin/--cli-bin)")
                continue
            if binary not in cache:
                cache[binary] = help_flags(binary)
            known = cache[binary]
            if known is None:
                continue
            flags = container_flags(c)
            missing = [f for f in flags if f not in known]
            if missing:
                fail(where, f"{field} command/args: {', '.join(missing)} not in "
                     f"`{program} --help` ({binary})")
            else:
                ok(f"{where}: {field}: {len(flags)} flags all in `{program} --help`")


def check_insecure(objects):
    for name, obj in objects:
        for field, c in containers(obj):
            flags = container_flags(c)
            if program_of(c) == "reenact-server" and "--insecure" in flags:
                absent = [f for f in ("--tls-cert", "--tls-key", "--auth") if f not in flags]
                if absent:
                    fail(f"{name} {ident(obj)}", f"{field}: --insecure without "
                         f"{', '.join(absent)} serves gRPC in the clear")
                else:
                    ok(f"{name} {ident(obj)}: {field}: --insecure comes with TLS and --auth")


# --- Dockerfile --------------------------------------------------------------

def parse_dockerfile(path):
    """(global ARG defaults, [stage]) with stage = {image, alias, lines}."""
    with open(path, encoding="utf-8") as f:
        text = f.read()
    logical, current = [], ""
    for line in text.splitlines():
        if not current and (not line.strip() or line.lstrip().startswith("#")):
            continue
        if current and line.lstrip().startswith("#"):
            continue  # a comment inside a continued instruction
        if line.rstrip().endswith("\\"):
            current += line.rstrip()[:-1] + " "
        else:
            logical.append(current + line)
            current = ""
    if current:
        logical.append(current)
    args, stages = {}, []
    for line in logical:
        words = line.split()
        instruction = words[0].upper()
        if instruction == "FROM":
            rest = [w for w in words[1:] if not w.startswith("--")]
            image = rest[0] if rest else ""
            image = re.sub(r"\$\{?(\w+)\}?", lambda m: args.get(m.group(1), m.group(0)), image)
            alias = rest[2] if len(rest) >= 3 and rest[1].upper() == "AS" else None
            stages.append({"image": image, "alias": alias, "lines": []})
        elif not stages and instruction == "ARG":
            m = re.match(r"ARG\s+(\w+)(?:=(.*))?", line.strip(), re.I)
            if m:
                args[m.group(1)] = (m.group(2) or "").strip().strip('"')
        elif stages:
            stages[-1]["lines"].append((instruction, line))
    return args, stages


def check_dockerfile(path, run_programs):
    """Checks the stages and what the last installs; returns the image's uid."""
    where = os.path.relpath(path, ROOT)
    try:
        _, stages = parse_dockerfile(path)
    except OSError as e:
        fail(where, f"cannot be read: {e}")
        return None
    if not stages:
        fail(where, "has no FROM")
        return None
    aliases = set()
    for i, stage in enumerate(stages):
        image = stage["image"]
        repository, _, tag = image.partition(":")
        if image in aliases:
            ok(f"{where}: FROM {image} (an earlier stage)")
        elif repository == "debian" and tag.startswith("bookworm"):
            ok(f"{where}: FROM {image} is Debian 12")
        elif "bookworm" in tag:
            ok(f"{where}: FROM {image} is built on Debian 12")
        else:
            fail(where, f"FROM {image} (stage {i + 1}) is not Debian 12 (bookworm)")
        if stage["alias"]:
            aliases.add(stage["alias"])
    final = stages[-1]
    if not final["image"].startswith("debian:bookworm"):
        fail(where, f"the last stage's FROM {final['image']} is not debian:bookworm-slim")
    users = [line.split()[1] for instruction, line in final["lines"] if instruction == "USER"]
    if not users or users[-1].split(":")[0] in ("root", "0"):
        fail(where, "the last stage runs as root (USER missing or root)")
    else:
        ok(f"{where}: the last stage runs as USER {users[-1]}")
    uid = None
    for instruction, line in final["lines"]:
        m = re.search(r"useradd\b.*--uid\s+(\d+)", line) if instruction == "RUN" else None
        if m:
            uid = int(m.group(1))
    installed = {}  # basename -> destination folder
    for instruction, line in final["lines"]:
        if instruction != "COPY":
            continue
        words = [w for w in line.split()[1:] if not w.startswith("--")]
        if len(words) < 2:
            continue
        sources, destination = words[:-1], words[-1]
        for source in sources:
            if destination.endswith("/"):
                installed[os.path.basename(source.rstrip("/"))] = destination.rstrip("/")
            else:
                installed[os.path.basename(destination)] = os.path.dirname(destination)
    for program in sorted(run_programs):
        folder = installed.get(program)
        if folder and folder.endswith("/bin"):
            ok(f"{where}: installs {program} into {folder}")
        else:
            fail(where, f"the last stage does not COPY {program} into a bin folder, "
                 "but the manifests run it")
    server_folder = installed.get("reenact-server")
    web = [d for b, d in installed.items() if b == "web" and d.endswith("/share/reenact")]
    expected = os.path.dirname(server_folder or "") + "/share/reenact"
    if server_folder and expected not in web:
        fail(where, "the web app is not copied to PREFIX/share/reenact/web beside "
             f"PREFIX/bin/reenact-server ({server_folder}), where the server looks for it")
    elif server_folder:
        ok(f"{where}: the web app is in {web[0]}/web, where reenact-server finds it")
    check_dockerfile_models(where, final, installed)
    return uid


def installed_models():
    """The tracker's model files that CMakeLists.txt's install() rule puts in
    DATADIR/reenact/models/tracker (paths relative to the checkout)."""
    try:
        with open(os.path.join(ROOT, "CMakeLists.txt"), encoding="utf-8") as f:
            text = f.read()
    except OSError:
        return []
    files = []
    for m in re.finditer(r"install\s*\(\s*FILES\s+([^)]*?)\s+DESTINATION\s+([^\s)]+)", text):
        if m.group(2).endswith("/reenact/models/tracker"):
            files += m.group(1).split()
    return files


# Ways a RUN could pass without the installed model: a masked exit status,
# or a model named past the lookup of the installed programs.
MASKED = re.compile(r"\|\|\s*(?:true|:|exit\s+0)\b|set\s+\+e\b")
BYPASS = re.compile(r"--model\b|REENACT_TRACKER_(?:MODEL|FOREST)=\S")


def check_dockerfile_models(where, final, installed):
    """The last stage installs the tracker's models where the installed
    programs look (PREFIX/share/reenact/models/tracker beside PREFIX/bin, see
    common/tracking/pose_net.h) and then runs the installed `reenact track`,
    so that a build whose image would not find the model fails."""
    models = installed_models()
    if not models:
        fail("CMakeLists.txt", "no install(FILES models/tracker/... DESTINATION "
             "${CMAKE_INSTALL_DATADIR}/reenact/models/tracker) rule: which models to check?")
        return
    for model in models:
        if not os.path.isfile(os.path.join(ROOT, model)):
            fail("CMakeLists.txt", f"installs {model}, which is not in the checkout")
    cli_folder = installed.get("reenact")
    if not (cli_folder and cli_folder.endswith("/bin")):
        fail(where, "the last stage does not COPY reenact into a bin folder, so nothing "
             "checks that its model is found")
        return
    expected = os.path.dirname(cli_folder) + "/share/reenact/models/tracker"
    copied_at = None  # index of the last line that installs a model
    names = {os.path.basename(model) for model in models}
    for index, (instruction, line) in enumerate(final["lines"]):
        if instruction in ("COPY", "ADD") and names & {os.path.basename(w.rstrip("/"))
                                                       for w in line.split()[1:-1]}:
            copied_at = index
    for model in models:
        folder = installed.get(os.path.basename(model))
        if folder != expected:
            fail(where, f"the last stage does not COPY {model} into {expected}/, where "
                 f"{cli_folder}/reenact and the other installed programs look for it "
                 f"(CMakeLists.txt installs it; found: {folder or 'not copied'})")
        else:
            ok(f"{where}: installs {model} into {folder}, where the installed programs "
               "look for it")
    # The check must come after the models are copied (from the start of the
    # stage where they are not: then it cannot pass either).
    start = 0 if copied_at is None else copied_at + 1
    runs = [line for instruction, line in final["lines"][start:]
            if instruction == "RUN" and re.search(r"(?<![\w/.-])reenact\s+track\b", line)]
    if not runs:
        fail(where, "no RUN of the last stage runs the installed `reenact track` after the "
             "models are copied, so a build whose model is not found would pass")
    for line in runs:
        if MASKED.search(line):
            fail(where, f"the RUN of `reenact track` masks its failure "
                 f"({MASKED.search(line).group(0)!r})")
        elif BYPASS.search(line):
            fail(where, f"the RUN of `reenact track` names a model itself "
                 f"({BYPASS.search(line).group(0)!r}) instead of testing the installed "
                 "lookup")
        else:
            ok(f"{where}: a RUN of the last stage runs the installed `reenact track`: the "
               "build fails when its model is not found")


# --- build context (.dockerignore) ------------------------------------------

# Paths the README's commands (and deploy/make-certs.sh, deploy/kubernetes'
# README) write into the checkout when run from it, which the build context
# must leave out: secrets first, then takes and what is made from them.
IGNORED_SAMPLES = [
    "tls/server.key", "tls/ca.pem", "tls/tokens.json", "certs/server.key", "certs/ca.pem",
    "server.key", "client.pem", "deploy/kubernetes/server.key", "clients/ca.pem",
    "capture.token", "node7.token", "deploy/kubernetes/worker.token",
    "tokens.json", "deploy/tokens.json",
    "take.mcap", "walk.mcap", "learner.mcap", "stored.mcap", "tests/take.mcap",
    "teacher.reen", "data/reenactments/x.reen", "data/catalog.sqlite",
    "data/catalog.sqlite-wal",
    "teacher.glb", "teacher.bvh", "teacher-appearance.mp4", "ar/video.mp4",
    "recording.mkv", "recording.oni",
    "sheet.png", "board.png", "c.jpg", "d.png",
    "frames/000000.png", "mirror/video.mp4", "reports/rep-001.json", "grade/grade.json",
    "out/demo/tls/server.key", "build/bin/reenact", ".git/config",
    "clients/web/node_modules/three/package.json", "clients/web/dist/index.html",
]


def dockerignore_patterns(path):
    """[(regex, exclusion)] of a .dockerignore, read as Docker reads it:
    comments and blank lines dropped, each pattern cleaned (a leading / and
    ./ removed), ! taking back what an earlier pattern left out."""
    patterns = []
    with open(path, encoding="utf-8") as f:
        for raw in f:
            line = raw.strip()
            if not line or line.startswith("#"):
                continue
            exclusion = line.startswith("!")
            if exclusion:
                line = line[1:].strip()
            line = os.path.normpath(line).lstrip("/")
            if not line or line == ".":
                continue
            patterns.append((docker_regex(line), exclusion))
    return patterns


def docker_regex(pattern):
    """The regular expression moby/patternmatcher builds of a pattern."""
    out, i = "", 0
    while i < len(pattern):
        ch = pattern[i]
        if ch == "*":
            if i + 1 < len(pattern) and pattern[i + 1] == "*":
                i += 1
                if i + 1 < len(pattern) and pattern[i + 1] == "/":
                    i += 1
                out += ".*" if i + 1 == len(pattern) else "(.*/)?"
            else:
                out += "[^/]*"
        elif ch == "?":
            out += "[^/]"
        elif ch == "\\" and i + 1 < len(pattern):
            i += 1
            out += re.escape(pattern[i])
        elif ch == "[":
            end = pattern.find("]", i + 1)
            if end < 0:
                out += re.escape(ch)
            else:
                body = pattern[i + 1:end]
                out += "[" + ("^" + body[1:] if body.startswith("^") else body) + "]"
                i = end
        else:
            out += re.escape(ch)
        i += 1
    return re.compile("^" + out + "$")


def docker_ignores(patterns, path):
    """Whether the build context leaves `path` (relative, with /) out: it or
    a folder above it matches a pattern, the last that decides winning."""
    parts = path.split("/")
    candidates = ["/".join(parts[:i]) for i in range(1, len(parts) + 1)]
    matched = False
    for regex, exclusion in patterns:
        if exclusion != matched:
            continue  # only a pattern that could change the answer
        if any(regex.match(c) for c in candidates):
            matched = not exclusion
    return matched


def context_sources(dockerfile):
    """The paths that COPY/ADD instructions take from the build context
    (not --from another stage or image), relative to it."""
    _, stages = parse_dockerfile(dockerfile)
    sources = []
    for stage in stages:
        for instruction, line in stage["lines"]:
            if instruction not in ("COPY", "ADD"):
                continue
            m = re.match(r"\S+\s+((?:--\S+\s+)*)(.*)", line.strip())
            if not m:
                continue
            flags, body = m.groups()
            if any(f.startswith("--from=") for f in flags.split()):
                continue
            if body.startswith("["):  # the exec form: ["SRC", ..., "DEST"]
                try:
                    words = json.loads(body)
                except ValueError:
                    fail(os.path.relpath(dockerfile, ROOT), f"cannot read {line.strip()}")
                    continue
            else:
                words = body.split()
            for source in words[:-1]:
                if re.match(r"^[a-z]+://", source):
                    continue  # ADD of a URL
                source = os.path.normpath(source).lstrip("/")
                sources.append("." if source in ("", ".") else source)
    return sources


def tracked_files():
    """The files git tracks in the checkout, or None outside git."""
    git = shutil.which("git")
    if not git or not os.path.exists(os.path.join(ROOT, ".git")):
        return None
    try:
        listed = subprocess.run([git, "-C", ROOT, "ls-files", "-z"], capture_output=True,
                                timeout=60, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    return [p for p in listed.decode("utf-8", "replace").split("\0") if p]


def check_docker_context(dockerignore, dockerfile):
    where = os.path.relpath(dockerignore, ROOT)
    try:
        patterns = dockerignore_patterns(dockerignore)
    except OSError as e:
        fail(where, f"cannot be read: {e} (the build context would hold the whole checkout)")
        return
    kept = [p for p in IGNORED_SAMPLES if not docker_ignores(patterns, p)]
    for path in kept:
        fail(where, f"{path} would be in the build context (the README's commands write "
             "such secrets or data into the checkout): add a pattern that leaves it out")
    if not kept:
        ok(f"{where}: leaves out secrets and data ({len(IGNORED_SAMPLES)} sample paths: "
           "tls/, certs/, *.key, *.pem, *.token, tokens.json, *.mcap, *.reen, *.glb, "
           "*.bvh, *.mp4, stores, reports, frames)")
    try:
        sources = context_sources(dockerfile)
    except OSError as e:
        fail(os.path.relpath(dockerfile, ROOT), f"cannot be read: {e}")
        return
    tracked = tracked_files()
    if tracked is None:
        print(f"note {where}: not a git checkout: only the COPY sources themselves are "
              "tried, not the files under them")
    for source in sources:
        if not glob_free(source):
            continue
        if source != "." and not os.path.exists(os.path.join(ROOT, source)):
            fail(os.path.relpath(dockerfile, ROOT), f"COPY {source}: not in the checkout")
            continue
        if source != "." and docker_ignores(patterns, source):
            fail(where, f"leaves out {source}, which the Dockerfile copies")
            continue
        if tracked is None:
            ok(f"{where}: keeps {source}, which the Dockerfile copies")
            continue
        files = [p for p in tracked if source == "." or p == source or
                 p.startswith(source.rstrip("/") + "/")]
        dropped = [p for p in files if docker_ignores(patterns, p)]
        if dropped:
            fail(where, f"leaves out {len(dropped)} tracked file(s) that COPY {source} "
                 f"copies: {', '.join(dropped[:8])}{' ...' if len(dropped) > 8 else ''} "
                 "(narrow the pattern, or take them back with !PATH)")
        else:
            ok(f"{where}: keeps all {len(files)} tracked file(s) that COPY {source} copies")


def glob_free(path):
    return not any(c in path for c in "*?[")


# --- kubectl -----------------------------------------------------------------

NEEDS_SERVER = re.compile(r"connection refused|couldn't get current server|unable to recognize|"
                          r"no configuration has been provided|dial tcp|i/o timeout|"
                          r"Unable to connect to the server|the server could not", re.I)


def check_kubectl(folder):
    kubectl = shutil.which("kubectl")
    if not kubectl:
        print("SKIPPED kubectl: not on PATH")
        return
    try:
        built = subprocess.run([kubectl, "kustomize", folder], capture_output=True, text=True,
                               timeout=120)
    except subprocess.TimeoutExpired:
        fail(folder, "kubectl kustomize timed out")
        return
    if built.returncode != 0:
        fail(folder, f"kubectl kustomize fails: {built.stderr.strip()}")
        return
    count = sum(1 for d in yaml.safe_load_all(built.stdout) if d)
    ok(f"kubectl kustomize {os.path.relpath(folder, ROOT)}: builds {count} objects")
    command = [kubectl, "apply", "--dry-run=client", "--validate=false", "--request-timeout=20s",
               "-k", folder, "-o", "name"]
    try:
        applied = subprocess.run(command, capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        print("SKIPPED kubectl apply --dry-run=client: no API server answered in 120 s")
        return
    output = (applied.stdout + applied.stderr).strip()
    if applied.returncode == 0:
        ok("kubectl apply --dry-run=client -k: " + " ".join(applied.stdout.split()))
    elif NEEDS_SERVER.search(output):
        first = next((l for l in output.splitlines() if NEEDS_SERVER.search(l)), output)
        first = first.split('err="', 1)[-1].strip().rstrip('"')
        print(f"SKIPPED kubectl apply --dry-run=client: it needs an API server for the "
              f"resource types, and none answers here ({first[:160]})")
    else:
        fail(folder, f"kubectl apply --dry-run=client -k fails: {output}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--manifests", default=os.path.join(ROOT, "deploy", "kubernetes"))
    parser.add_argument("--dockerfile",
                        default=os.path.join(ROOT, "deploy", "docker", "Dockerfile"))
    parser.add_argument("--dockerignore", default=os.path.join(ROOT, ".dockerignore"),
                        help="the build context's .dockerignore (the Dockerfile builds from "
                             "the top of the checkout)")
    parser.add_argument("--server-bin", help="reenact-server, for its --help and metric names")
    parser.add_argument("--worker-bin", help="reenact-worker, for its --help")
    parser.add_argument("--cli-bin", help="reenact, for its --help (if a manifest runs it)")
    parser.add_argument("--skip-flag-check", action="store_true",
                        help="do not compare containers' flags with the programs' --help")
    parser.add_argument("--skip-kubectl", action="store_true", help="do not run kubectl")
    args = parser.parse_args()
    folder = os.path.abspath(args.manifests)
    for flag, path in (("--server-bin", args.server_bin), ("--worker-bin", args.worker_bin),
                       ("--cli-bin", args.cli_bin)):
        if path and not os.access(path, os.X_OK):
            fail(flag, f"{path} is not an executable")

    objects, kustomization = load_manifests(folder)
    objects = [(n, o) for n, o in objects if check_api(n, o)]
    check_kustomization(folder, kustomization, objects)
    run_programs = {program_of(c) for _, o in objects if o.get("kind") in WORKLOADS
                    for _, c in containers(o)} & set(PROGRAMS)
    uid = check_dockerfile(os.path.abspath(args.dockerfile), run_programs)
    check_docker_context(os.path.abspath(args.dockerignore), os.path.abspath(args.dockerfile))

    workloads = []
    for name, obj in objects:
        if obj.get("kind") in WORKLOADS:
            labels, ports = check_workload(name, obj, uid)
            workloads.append({"kind": obj["kind"], "name": obj["metadata"]["name"],
                              "id": ident(obj), "labels": labels, "ports": ports,
                              "programs": {program_of(c) for _, c in containers(obj)}})
    for name, obj in objects:
        if obj.get("kind") == "Service":
            check_service(name, obj, workloads)
        elif obj.get("kind") == "HorizontalPodAutoscaler":
            check_hpa(name, obj, workloads, args.server_bin)
    check_governing_services(objects)
    if not any(o.get("kind") == "HorizontalPodAutoscaler" for _, o in objects):
        fail(folder, "no HorizontalPodAutoscaler for the workers")
    check_insecure(objects)

    if args.skip_flag_check:
        print("SKIPPED flag check: --skip-flag-check")
    else:
        check_flags(objects, {"reenact-server": args.server_bin,
                              "reenact-worker": args.worker_bin, "reenact": args.cli_bin})
    if args.skip_kubectl:
        print("SKIPPED kubectl: --skip-kubectl")
    else:
        check_kubectl(folder)

    if problems:
        print(f"\n{len(problems)} problem(s) in the deployment files:")
        for p in problems:
            print(f"  {p}")
        return 1
    print("\ndeployment files: all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
