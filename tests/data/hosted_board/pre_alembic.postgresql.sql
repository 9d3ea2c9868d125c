--
-- PostgreSQL database dump
--


-- Dumped from database version 15.18 (Debian 15.18-0+deb12u1)
-- Dumped by pg_dump version 15.18 (Debian 15.18-0+deb12u1)

SET statement_timeout = 0;
SET lock_timeout = 0;
SET idle_in_transaction_session_timeout = 0;
SET client_encoding = 'UTF8';
SET standard_conforming_strings = on;
SELECT pg_catalog.set_config('search_path', '', false);
SET check_function_bodies = false;
SET xmloption = content;
SET client_min_messages = warning;
SET row_security = off;

SET default_tablespace = '';

SET default_table_access_method = heap;

--
-- Name: accounts; Type: TABLE; Schema: public; Owner: -
--

CREATE TABLE public.accounts (
    id integer NOT NULL,
    name character varying(100) NOT NULL,
    token_hash character varying(64) NOT NULL,
    admin boolean NOT NULL,
    created double precision NOT NULL
);


--
-- Name: accounts_id_seq; Type: SEQUENCE; Schema: public; Owner: -
--

CREATE SEQUENCE public.accounts_id_seq
    AS integer
    START WITH 1
    INCREMENT BY 1
    NO MINVALUE
    NO MAXVALUE
    CACHE 1;


--
-- Name: accounts_id_seq; Type: SEQUENCE OWNED BY; Schema: public; Owner: -
--

ALTER SEQUENCE public.accounts_id_seq OWNED BY public.accounts.id;


--
-- Name: board_meta; Type: TABLE; Schema: public; Owner: -
--

CREATE TABLE public.board_meta (
    name character varying(100) NOT NULL,
    value character varying(200) NOT NULL
);


--
-- Name: hidden_seeds; Type: TABLE; Schema: public; Owner: -
--

CREATE TABLE public.hidden_seeds (
    id integer NOT NULL,
    track character varying(100) NOT NULL,
    track_hash character varying(64) NOT NULL,
    version integer NOT NULL,
    seeds text NOT NULL,
    salt character varying(64) NOT NULL,
    commitment character varying(71) NOT NULL,
    created double precision NOT NULL
);


--
-- Name: hidden_seeds_id_seq; Type: SEQUENCE; Schema: public; Owner: -
--

CREATE SEQUENCE public.hidden_seeds_id_seq
    AS integer
    START WITH 1
    INCREMENT BY 1
    NO MINVALUE
    NO MAXVALUE
    CACHE 1;


--
-- Name: hidden_seeds_id_seq; Type: SEQUENCE OWNED BY; Schema: public; Owner: -
--

ALTER SEQUENCE public.hidden_seeds_id_seq OWNED BY public.hidden_seeds.id;


--
-- Name: jobs; Type: TABLE; Schema: public; Owner: -
--

CREATE TABLE public.jobs (
    submission_id integer NOT NULL,
    state character varying(8) NOT NULL,
    lease_owner character varying(200),
    lease_until double precision,
    fence bigint NOT NULL,
    heartbeat_at double precision,
    CONSTRAINT job_state_known CHECK (((state)::text = ANY ((ARRAY['queued'::character varying, 'running'::character varying, 'done'::character varying, 'failed'::character varying])::text[])))
);


--
-- Name: packages; Type: TABLE; Schema: public; Owner: -
--

CREATE TABLE public.packages (
    sha256 character varying(71) NOT NULL,
    bytes bytea NOT NULL,
    size bigint NOT NULL,
    created double precision NOT NULL
);


--
-- Name: rows; Type: TABLE; Schema: public; Owner: -
--

CREATE TABLE public.rows (
    submission_id integer NOT NULL,
    scenario character varying(100) NOT NULL,
    seed_index integer NOT NULL,
    seed bigint NOT NULL,
    workforce_cost double precision NOT NULL,
    utilization double precision NOT NULL,
    downtime double precision NOT NULL,
    nsw double precision NOT NULL,
    episode_length integer NOT NULL,
    invalid_actions integer NOT NULL,
    decision_ms_p50 double precision,
    decision_ms_p99 double precision,
    cpu_s double precision,
    machine text,
    finished double precision NOT NULL
);


--
-- Name: secrets; Type: TABLE; Schema: public; Owner: -
--

CREATE TABLE public.secrets (
    name character varying(100) NOT NULL,
    value character varying(200) NOT NULL
);


--
-- Name: submissions; Type: TABLE; Schema: public; Owner: -
--

CREATE TABLE public.submissions (
    id integer NOT NULL,
    account_id integer NOT NULL,
    track character varying(100) NOT NULL,
    track_hash character varying(64) NOT NULL,
    phase character varying(8) NOT NULL,
    package_sha character varying(71) NOT NULL,
    entry character varying(300) NOT NULL,
    name character varying(100) NOT NULL,
    state character varying(8) NOT NULL,
    reason text NOT NULL,
    created double precision NOT NULL,
    updated double precision NOT NULL,
    attempts integer NOT NULL,
    hidden_version integer,
    log text NOT NULL,
    result text,
    fault character varying(8) DEFAULT ''::character varying NOT NULL,
    kind character varying(20) DEFAULT ''::character varying NOT NULL,
    spent_s double precision DEFAULT '0'::double precision NOT NULL,
    withdrawn double precision,
    CONSTRAINT phase_known CHECK (((phase)::text = ANY ((ARRAY['dev'::character varying, 'test'::character varying])::text[]))),
    CONSTRAINT state_known CHECK (((state)::text = ANY ((ARRAY['queued'::character varying, 'running'::character varying, 'done'::character varying, 'failed'::character varying])::text[])))
);


--
-- Name: submissions_id_seq; Type: SEQUENCE; Schema: public; Owner: -
--

CREATE SEQUENCE public.submissions_id_seq
    AS integer
    START WITH 1
    INCREMENT BY 1
    NO MINVALUE
    NO MAXVALUE
    CACHE 1;


--
-- Name: submissions_id_seq; Type: SEQUENCE OWNED BY; Schema: public; Owner: -
--

ALTER SEQUENCE public.submissions_id_seq OWNED BY public.submissions.id;


--
-- Name: accounts id; Type: DEFAULT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.accounts ALTER COLUMN id SET DEFAULT nextval('public.accounts_id_seq'::regclass);


--
-- Name: hidden_seeds id; Type: DEFAULT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.hidden_seeds ALTER COLUMN id SET DEFAULT nextval('public.hidden_seeds_id_seq'::regclass);


--
-- Name: submissions id; Type: DEFAULT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.submissions ALTER COLUMN id SET DEFAULT nextval('public.submissions_id_seq'::regclass);


--
-- Data for Name: accounts; Type: TABLE DATA; Schema: public; Owner: -
--

INSERT INTO public.accounts VALUES (1, 'admin', '6f4a0a6a89f7476a72daee3a0310f9e4263b3f2c486cb6654baf76e2269edf70', true, 1795825030.921198);
INSERT INTO public.accounts VALUES (2, 'alice', 'cc70b2652903d3f005b688e578301a6bd3a27c59eb92f3e5e9ccd4c992ef5620', false, 1795825030.9259448);
INSERT INTO public.accounts VALUES (3, 'bob', 'f23843a8c059346e45b9c20050a80452d7c2d4ef243103a4a88373e7c23c4836', false, 1795825030.9282985);


--
-- Data for Name: board_meta; Type: TABLE DATA; Schema: public; Owner: -
--

INSERT INTO public.board_meta VALUES ('schema_version', '2');
INSERT INTO public.board_meta VALUES ('test_ended:tiny', '1795825031.08399');


--
-- Data for Name: hidden_seeds; Type: TABLE DATA; Schema: public; Owner: -
--

INSERT INTO public.hidden_seeds VALUES (1, 'tiny', '20f062348dba032f', 1, '[890493914811623414, 577452470395281308, 3423297954640433023, 4042301153386721853, 2143196939277154443, 1079448933138771129, 2153091930609229125, 1930365846455398348, 2800286306480454688, 2868313978423477112, 557480869914638304, 3021430338971068192, 3644361518320225209, 3131778338164451816, 4580582118773438633, 1381229053698909001, 3935938341725554697, 678685633597934013, 3966831219126335520, 4480842242021516764, 2888987269270650691, 826224194653543297, 1845120180302606628, 3876189908873959689, 701973800505485637, 1428803241166272074, 1519364247303135096, 3561062362498507341, 2582760667583531987, 1958699341039495986, 2745198387649513075, 2949318118941747169, 3621712873923576444, 1605936477591202730, 3548466307600323177, 1776775640044256122, 524897148342754515, 3378341776820860940, 4091081222297305819, 3092072864672850192, 3211908739989885669, 2970444428626509014, 2448368172913469690, 641256033019778528, 2873375129634819838, 754408329101085145, 2694990102066201332, 820951307415706103, 975842222964871076, 921828006863773097]', '7a11da1cc2c112348a1c8c70f1cb0ac7', 'sha256:4e8209b1e526eba3572638c5c3441da30dc8d33e55eebdb17fd218256b64f2b3', 1795825030.999954);


--
-- Data for Name: jobs; Type: TABLE DATA; Schema: public; Owner: -
--

INSERT INTO public.jobs VALUES (1, 'done', 'tester', NULL, 1, 1795825030.973383);
INSERT INTO public.jobs VALUES (2, 'failed', 'tester', NULL, 1, 1795825030.995579);
INSERT INTO public.jobs VALUES (3, 'done', 'tester', NULL, 1, 1795825031.043555);
INSERT INTO public.jobs VALUES (4, 'done', 'tester', NULL, 1, 1795825031.065235);
INSERT INTO public.jobs VALUES (5, 'queued', NULL, NULL, 0, NULL);


--
-- Data for Name: packages; Type: TABLE DATA; Schema: public; Owner: -
--

INSERT INTO public.packages VALUES ('sha256:0acf7091e66f109ed6935695cd683e1744f23c16a1d5047e2eece888d90b93d2', '\x7061636b6167652030', 9, 1795825030.932396);
INSERT INTO public.packages VALUES ('sha256:a33c689cfa399003b853ec27f49a48fdf736a0e30d6a0e5feceb0e7772196b11', '\x7061636b6167652031', 9, 1795825030.9346402);
INSERT INTO public.packages VALUES ('sha256:3dbc44e0c8030e76f14931d5d350131b12b38b20e9bd8bc6a9500eefebd223d5', '\x7061636b6167652032', 9, 1795825030.9362178);
INSERT INTO public.packages VALUES ('sha256:788c332e3562616a2ad7a8318d60a8e26b73e7a282e83ec36cb8fc2397ea7650', '\x7061636b6167652033', 9, 1795825030.938214);


--
-- Data for Name: rows; Type: TABLE DATA; Schema: public; Owner: -
--

INSERT INTO public.rows VALUES (1, '', 0, 1000, 0.5, 0.5, 0.5, 0.5, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825030.967127);
INSERT INTO public.rows VALUES (1, '', 1, 1001, 0.5, 0.5, 0.5, 0.51, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825030.967127);
INSERT INTO public.rows VALUES (1, '', 2, 1002, 0.5, 0.5, 0.5, 0.52, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825030.967127);
INSERT INTO public.rows VALUES (2, '', 0, 1000, 0.5, 0.5, 0.5, 0.25, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825030.991464);
INSERT INTO public.rows VALUES (2, '', 1, 1001, 0.5, 0.5, 0.5, 0.26, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825030.991464);
INSERT INTO public.rows VALUES (2, '', 2, 1002, 0.5, 0.5, 0.5, 0.27, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825030.991464);
INSERT INTO public.rows VALUES (3, '', 0, 890493914811623414, 0.5, 0.5, 0.5, 0.75, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 1, 577452470395281308, 0.5, 0.5, 0.5, 0.76, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 2, 3423297954640433023, 0.5, 0.5, 0.5, 0.77, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 3, 4042301153386721853, 0.5, 0.5, 0.5, 0.78, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 4, 2143196939277154443, 0.5, 0.5, 0.5, 0.79, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 5, 1079448933138771129, 0.5, 0.5, 0.5, 0.8, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 6, 2153091930609229125, 0.5, 0.5, 0.5, 0.81, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 7, 1930365846455398348, 0.5, 0.5, 0.5, 0.8200000000000001, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 8, 2800286306480454688, 0.5, 0.5, 0.5, 0.83, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 9, 2868313978423477112, 0.5, 0.5, 0.5, 0.84, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 10, 557480869914638304, 0.5, 0.5, 0.5, 0.85, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 11, 3021430338971068192, 0.5, 0.5, 0.5, 0.86, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 12, 3644361518320225209, 0.5, 0.5, 0.5, 0.87, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 13, 3131778338164451816, 0.5, 0.5, 0.5, 0.88, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 14, 4580582118773438633, 0.5, 0.5, 0.5, 0.89, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 15, 1381229053698909001, 0.5, 0.5, 0.5, 0.9, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 16, 3935938341725554697, 0.5, 0.5, 0.5, 0.91, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 17, 678685633597934013, 0.5, 0.5, 0.5, 0.92, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 18, 3966831219126335520, 0.5, 0.5, 0.5, 0.9299999999999999, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 19, 4480842242021516764, 0.5, 0.5, 0.5, 0.94, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 20, 2888987269270650691, 0.5, 0.5, 0.5, 0.95, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 21, 826224194653543297, 0.5, 0.5, 0.5, 0.96, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 22, 1845120180302606628, 0.5, 0.5, 0.5, 0.97, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 23, 3876189908873959689, 0.5, 0.5, 0.5, 0.98, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 24, 701973800505485637, 0.5, 0.5, 0.5, 0.99, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 25, 1428803241166272074, 0.5, 0.5, 0.5, 1, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 26, 1519364247303135096, 0.5, 0.5, 0.5, 1.01, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 27, 3561062362498507341, 0.5, 0.5, 0.5, 1.02, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 28, 2582760667583531987, 0.5, 0.5, 0.5, 1.03, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 29, 1958699341039495986, 0.5, 0.5, 0.5, 1.04, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 30, 2745198387649513075, 0.5, 0.5, 0.5, 1.05, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 31, 2949318118941747169, 0.5, 0.5, 0.5, 1.06, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 32, 3621712873923576444, 0.5, 0.5, 0.5, 1.07, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 33, 1605936477591202730, 0.5, 0.5, 0.5, 1.08, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 34, 3548466307600323177, 0.5, 0.5, 0.5, 1.09, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 35, 1776775640044256122, 0.5, 0.5, 0.5, 1.1, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 36, 524897148342754515, 0.5, 0.5, 0.5, 1.1099999999999999, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 37, 3378341776820860940, 0.5, 0.5, 0.5, 1.12, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 38, 4091081222297305819, 0.5, 0.5, 0.5, 1.13, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 39, 3092072864672850192, 0.5, 0.5, 0.5, 1.1400000000000001, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 40, 3211908739989885669, 0.5, 0.5, 0.5, 1.15, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 41, 2970444428626509014, 0.5, 0.5, 0.5, 1.16, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 42, 2448368172913469690, 0.5, 0.5, 0.5, 1.17, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 43, 641256033019778528, 0.5, 0.5, 0.5, 1.18, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 44, 2873375129634819838, 0.5, 0.5, 0.5, 1.19, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 45, 754408329101085145, 0.5, 0.5, 0.5, 1.2, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 46, 2694990102066201332, 0.5, 0.5, 0.5, 1.21, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 47, 820951307415706103, 0.5, 0.5, 0.5, 1.22, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 48, 975842222964871076, 0.5, 0.5, 0.5, 1.23, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (3, '', 49, 921828006863773097, 0.5, 0.5, 0.5, 1.24, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.018246);
INSERT INTO public.rows VALUES (4, '', 0, 1000, 0.5, 0.5, 0.5, 0.4, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.060526);
INSERT INTO public.rows VALUES (4, '', 1, 1001, 0.5, 0.5, 0.5, 0.41000000000000003, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.060526);
INSERT INTO public.rows VALUES (4, '', 2, 1002, 0.5, 0.5, 0.5, 0.42000000000000004, 20, 0, 0.1, 0.2, 0.01, 'test machine', 1795825031.060526);


--
-- Data for Name: secrets; Type: TABLE DATA; Schema: public; Owner: -
--

INSERT INTO public.secrets VALUES ('key_secret', 'd5f6daead074d6108426ce6ed9431090663c7bfb47e0d9639280b00fab242384');


--
-- Data for Name: submissions; Type: TABLE DATA; Schema: public; Owner: -
--

INSERT INTO public.submissions VALUES (1, 2, 'tiny', '20f062348dba032f', 'dev', 'sha256:0acf7091e66f109ed6935695cd683e1744f23c16a1d5047e2eece888d90b93d2', 'pa:Policy', 'alice-one', 'done', '', 1795825030.944934, 1795825030.973383, 1, NULL, '', '{"fake": true}', '', '', 0, NULL);
INSERT INTO public.submissions VALUES (2, 3, 'tiny', '20f062348dba032f', 'dev', 'sha256:a33c689cfa399003b853ec27f49a48fdf736a0e30d6a0e5feceb0e7772196b11', 'pb:Policy', 'bob-one', 'failed', 'act took longer than 10 s (the act time limit)', 1795825030.9802122, 1795825030.995579, 1, NULL, '', NULL, 'policy', 'timed out', 0, NULL);
INSERT INTO public.submissions VALUES (3, 2, 'tiny', '20f062348dba032f', 'test', 'sha256:3dbc44e0c8030e76f14931d5d350131b12b38b20e9bd8bc6a9500eefebd223d5', 'pa:Policy', 'alice-test', 'done', '', 1795825031.0061684, 1795825031.043555, 1, 1, '', '{"fake": true}', '', '', 0, NULL);
INSERT INTO public.submissions VALUES (4, 3, 'tiny', '20f062348dba032f', 'dev', 'sha256:788c332e3562616a2ad7a8318d60a8e26b73e7a282e83ec36cb8fc2397ea7650', 'pb:Other', 'bob-two', 'done', '', 1795825031.0482235, 1795825031.0693953, 1, NULL, '', '{"fake": true}', '', '', 0, 1795825031.0693953);
INSERT INTO public.submissions VALUES (5, 2, 'tiny', '20f062348dba032f', 'dev', 'sha256:a33c689cfa399003b853ec27f49a48fdf736a0e30d6a0e5feceb0e7772196b11', 'pb:Policy', 'alice-queued', 'queued', '', 1795825031.0762699, 1795825031.0762699, 0, NULL, '', NULL, '', '', 0, NULL);


--
-- Name: accounts_id_seq; Type: SEQUENCE SET; Schema: public; Owner: -
--

SELECT pg_catalog.setval('public.accounts_id_seq', 3, true);


--
-- Name: hidden_seeds_id_seq; Type: SEQUENCE SET; Schema: public; Owner: -
--

SELECT pg_catalog.setval('public.hidden_seeds_id_seq', 1, true);


--
-- Name: submissions_id_seq; Type: SEQUENCE SET; Schema: public; Owner: -
--

SELECT pg_catalog.setval('public.submissions_id_seq', 5, true);


--
-- Name: accounts accounts_name_key; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.accounts
    ADD CONSTRAINT accounts_name_key UNIQUE (name);


--
-- Name: accounts accounts_pkey; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.accounts
    ADD CONSTRAINT accounts_pkey PRIMARY KEY (id);


--
-- Name: accounts accounts_token_hash_key; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.accounts
    ADD CONSTRAINT accounts_token_hash_key UNIQUE (token_hash);


--
-- Name: board_meta board_meta_pkey; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.board_meta
    ADD CONSTRAINT board_meta_pkey PRIMARY KEY (name);


--
-- Name: hidden_seeds hidden_seeds_pkey; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.hidden_seeds
    ADD CONSTRAINT hidden_seeds_pkey PRIMARY KEY (id);


--
-- Name: hidden_seeds hidden_seeds_track_version_key; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.hidden_seeds
    ADD CONSTRAINT hidden_seeds_track_version_key UNIQUE (track, version);


--
-- Name: jobs jobs_pkey; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.jobs
    ADD CONSTRAINT jobs_pkey PRIMARY KEY (submission_id);


--
-- Name: rows one_row_per_unit; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.rows
    ADD CONSTRAINT one_row_per_unit UNIQUE (submission_id, scenario, seed_index);


--
-- Name: packages packages_pkey; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.packages
    ADD CONSTRAINT packages_pkey PRIMARY KEY (sha256);


--
-- Name: submissions same_package_per_account; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.submissions
    ADD CONSTRAINT same_package_per_account UNIQUE (account_id, package_sha, entry, track, phase);


--
-- Name: secrets secrets_pkey; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.secrets
    ADD CONSTRAINT secrets_pkey PRIMARY KEY (name);


--
-- Name: submissions submissions_pkey; Type: CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.submissions
    ADD CONSTRAINT submissions_pkey PRIMARY KEY (id);


--
-- Name: jobs_state; Type: INDEX; Schema: public; Owner: -
--

CREATE INDEX jobs_state ON public.jobs USING btree (state, lease_until);


--
-- Name: submissions_account; Type: INDEX; Schema: public; Owner: -
--

CREATE INDEX submissions_account ON public.submissions USING btree (account_id, phase, created);


--
-- Name: jobs jobs_submission_id_fkey; Type: FK CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.jobs
    ADD CONSTRAINT jobs_submission_id_fkey FOREIGN KEY (submission_id) REFERENCES public.submissions(id);


--
-- Name: rows rows_submission_id_fkey; Type: FK CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.rows
    ADD CONSTRAINT rows_submission_id_fkey FOREIGN KEY (submission_id) REFERENCES public.submissions(id);


--
-- Name: submissions submissions_account_id_fkey; Type: FK CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.submissions
    ADD CONSTRAINT submissions_account_id_fkey FOREIGN KEY (account_id) REFERENCES public.accounts(id);


--
-- Name: submissions submissions_package_sha_fkey; Type: FK CONSTRAINT; Schema: public; Owner: -
--

ALTER TABLE ONLY public.submissions
    ADD CONSTRAINT submissions_package_sha_fkey FOREIGN KEY (package_sha) REFERENCES public.packages(sha256);


--
-- PostgreSQL database dump complete
--


