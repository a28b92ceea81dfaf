// Validates every object of the Kubernetes manifests against the JSON schema
// of its apiVersion/kind as Kubernetes 1.27 publishes it (npm
// kubernetes-models: the schemas of the API's OpenAPI document, compiled for
// ajv; they ship in the package, so this runs offline), written
// independently of tests/deploy/check_kubernetes.py.
//   node check_k8s_schema.mjs [DIR_OR_FILE ...]   (default: deploy/kubernetes)
// Reads every *.yaml / *.yml of a folder (each a stream of documents) as
// Kubernetes does (YAML 1.1: 0440 is octal, yes/no/on/off are booleans),
// but kustomization.yaml, which is kubectl's input, not a cluster object.
// Prints one line per object checked and one per violation:
//   FAIL server.yaml:120 StatefulSet/reenact-server
//        /spec/template/spec/containers/0/ports/0/containerPort: must be integer
// An apiVersion/kind without a schema here (a removed API version, a typo,
// a custom resource) is a violation too.
// What it cannot see: like Kubernetes' OpenAPI schemas, these do not forbid
// unknown fields, so a misspelt field name passes here (the API server's
// strict field validation refuses it); tests/deploy/check_kubernetes.py
// checks the objects against each other and the programs.
// Exit status: 0 when every object is valid, 1 otherwise, 2 on bad usage,
// 77 (skipped) when the npm packages are not installed.
// Setup: npm install --prefix tests/js   (deploy/setup-debian.sh does it)
import { readdirSync, readFileSync, statSync } from "node:fs";
import { basename, dirname, join, relative, resolve } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const root = resolve(here, "..", "..");

let YAML;
try {
  YAML = await import("yaml");
  await import("kubernetes-models/v1");
} catch (e) {
  console.log(`SKIPPED: the npm packages of tests/js are missing ` +
              `(npm install --prefix tests/js): ${e.message.split("\n")[0]}`);
  process.exit(77);
}

const KUSTOMIZATION = new Set(["kustomization.yaml", "kustomization.yml"]);
// The package keeps the schemas of API versions that Kubernetes no longer
// serves; these are gone by 1.27 (the release that removed each).
const REMOVED = {
  "extensions/v1beta1": "1.22", "apps/v1beta1": "1.16", "apps/v1beta2": "1.16",
  "networking.k8s.io/v1beta1": "1.22", "autoscaling/v2beta1": "1.25",
  "autoscaling/v2beta2": "1.26", "policy/v1beta1": "1.25", "batch/v1beta1": "1.25",
  "discovery.k8s.io/v1beta1": "1.25", "events.k8s.io/v1beta1": "1.25",
  "node.k8s.io/v1beta1": "1.25", "rbac.authorization.k8s.io/v1beta1": "1.22",
  "scheduling.k8s.io/v1beta1": "1.22", "storage.k8s.io/v1beta1": "1.27",
  "admissionregistration.k8s.io/v1beta1": "1.22", "apiextensions.k8s.io/v1beta1": "1.22",
  "apiregistration.k8s.io/v1beta1": "1.22", "authentication.k8s.io/v1beta1": "1.22",
  "authorization.k8s.io/v1beta1": "1.22", "certificates.k8s.io/v1beta1": "1.22",
  "coordination.k8s.io/v1beta1": "1.22", "flowcontrol.apiserver.k8s.io/v1beta1": "1.26",
};
let problems = 0;
let checked = 0;

function fail(where, message) {
  problems++;
  console.log(`FAIL ${where}: ${message}`);
}

// The files named on the command line: folders give their manifests.
function manifestFiles(args) {
  const files = [];
  for (const arg of args.length ? args : [join(root, "deploy", "kubernetes")]) {
    let stat;
    try {
      stat = statSync(arg);
    } catch (e) {
      fail(arg, `cannot be read: ${e.message}`);
      continue;
    }
    if (!stat.isDirectory()) {
      files.push(arg);
      continue;
    }
    const names = readdirSync(arg).filter((n) => /\.ya?ml$/.test(n) && !KUSTOMIZATION.has(n));
    if (!names.length) fail(arg, "holds no manifests");
    files.push(...names.sort().map((n) => join(arg, n)));
  }
  return files;
}

// The model class of an apiVersion/kind: kubernetes-models/<group>/<version>
// exports one class per kind ("v1" is the core group).
const modules = new Map();
async function modelOf(apiVersion, kind) {
  if (typeof apiVersion !== "string" || !/^[a-z0-9.-]*\/?v[0-9a-z]+$/.test(apiVersion)) return null;
  if (!modules.has(apiVersion)) {
    try {
      modules.set(apiVersion, await import(`kubernetes-models/${apiVersion}`));
    } catch {
      modules.set(apiVersion, null);
    }
  }
  const model = modules.get(apiVersion)?.[kind];
  // The modules also export the types of fields (ObjectMeta...): only a
  // class of that very apiVersion/kind is an object of the API.
  return model && model.apiVersion === apiVersion && model.kind === kind ? model : null;
}

// The line of a JSON pointer in the YAML document, for the message.
function lineOf(doc, counter, pointer) {
  const path = pointer.split("/").slice(1)
    .map((p) => p.replace(/~1/g, "/").replace(/~0/g, "~"))
    .map((p) => (/^\d+$/.test(p) ? Number(p) : p));
  for (let n = path.length; n >= 0; n--) {
    const node = n ? doc.getIn(path.slice(0, n), true) : doc.contents;
    if (node && node.range) return counter.linePos(node.range[0]).line;
  }
  return null;
}

// ajv's message for an error, with what it needed where that helps.
function describe(error) {
  const { keyword, params, message } = error;
  if (keyword === "required") return `${params.missingProperty} is required`;
  if (keyword === "enum") return `${message}: ${params.allowedValues.join(", ")}`;
  if (keyword === "additionalProperties") return `unknown field ${params.additionalProperty}`;
  return message;
}

async function checkFile(file) {
  const name = relative(process.cwd(), file) || basename(file);
  let text;
  try {
    text = readFileSync(file, "utf8");
  } catch (e) {
    fail(name, `cannot be read: ${e.message}`);
    return;
  }
  const counter = new YAML.LineCounter();
  const docs = YAML.parseAllDocuments(text, { version: "1.1", lineCounter: counter });
  if (!Array.isArray(docs)) {  // An empty stream.
    fail(name, "holds no objects");
    return;
  }
  let objects = 0;
  for (const [i, doc] of docs.entries()) {
    const where = `${name} (document ${i + 1})`;
    if (doc.errors.length) {
      for (const e of doc.errors) fail(`${name}:${counter.linePos(e.pos[0]).line}`, e.message);
      continue;
    }
    const object = doc.toJS({ maxAliasCount: 100 });
    if (object === null || object === undefined) continue;  // "---" alone
    objects++;
    if (typeof object !== "object" || Array.isArray(object)) {
      fail(where, "is not a mapping (an object needs apiVersion, kind, metadata)");
      continue;
    }
    const { apiVersion, kind } = object;
    const id = `${kind}/${object.metadata?.name}`;
    if (REMOVED[apiVersion]) {
      fail(`${name}:${lineOf(doc, counter, "/apiVersion")} ${id}`,
           `apiVersion ${apiVersion} is no longer served (removed in Kubernetes ` +
           `${REMOVED[apiVersion]})`);
      continue;
    }
    const Model = await modelOf(apiVersion, kind);
    if (!Model) {
      fail(`${name}:${lineOf(doc, counter, "/kind")} ${id}`,
           `no schema for apiVersion ${JSON.stringify(apiVersion)} kind ` +
           `${JSON.stringify(kind)} in Kubernetes 1.27 (removed, misspelt, or a custom resource)`);
      continue;
    }
    checked++;
    try {
      new Model(object).validate();
      console.log(`ok   ${name} ${id}: valid ${apiVersion} ${kind}`);
    } catch (e) {
      if (!Array.isArray(e.errors)) throw e;
      // Alternatives (oneOf, anyOf) report the same place more than once.
      const seen = new Set();
      for (const error of e.errors) {
        const message = `${error.instancePath || "/"}: ${describe(error)}`;
        if (seen.has(message)) continue;
        seen.add(message);
        fail(`${name}:${lineOf(doc, counter, error.instancePath)} ${id}`, message);
      }
    }
  }
  if (!objects) fail(name, "holds no objects");
}

const args = process.argv.slice(2);
if (args.some((a) => a.startsWith("-"))) {
  console.error("usage: node check_k8s_schema.mjs [DIR_OR_FILE ...]");
  process.exit(2);
}
for (const file of manifestFiles(args)) await checkFile(file);
if (problems) {
  console.log(`\n${problems} schema violation(s) in the manifests (${checked} object(s) checked)`);
  process.exit(1);
}
console.log(`\nmanifests: ${checked} object(s) valid against the Kubernetes 1.27 schemas`);
